"""Example sweep files (package data): ``rollfric sweep --list``, ``rollfric sweep NAME``."""
