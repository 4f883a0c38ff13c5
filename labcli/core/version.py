"""The toolkit's version (written into every run file and model)."""

__version__ = "0.1.0"
