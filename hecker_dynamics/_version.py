"""The package's version, kept apart so any layer can record it (session records do)."""

__all__ = ["__version__"]

__version__ = "0.1.0"
