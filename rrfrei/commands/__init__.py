"""CLI commands, one module each (see rrfrei.cli)."""
