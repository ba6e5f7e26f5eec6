"""Bundled data (SYNTHETIC isolator tests); read with :func:`rrfrei.load_test`."""
