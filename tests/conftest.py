"""Fixtures shared by the test packages; plain helper functions live in ``support.py``."""
