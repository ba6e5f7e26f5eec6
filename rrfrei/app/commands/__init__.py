"""CLI commands, one module each (see rrfrei.app.cli)."""
