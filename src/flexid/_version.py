"""flexid's version, in one place: the front door shows it, records and exports carry it."""

__all__ = ["__version__"]

__version__ = "0.1.0"
