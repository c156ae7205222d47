"""Ergonomic assessment of the synthesised motion (RULA per frame)."""
