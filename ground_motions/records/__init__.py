"""Bundled accelerogram files (package data; see PROVENANCE.md in this folder)."""
