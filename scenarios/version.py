"""The package version: one place, at the bottom layer, stamped on every file written."""

__version__ = "0.1.0"
