"""The toolkit's version, in this one place: written into every run file and model, and read
by the packaging (``pyproject.toml``'s ``dynamic = ["version"]``)."""

__version__ = "0.1.0"
