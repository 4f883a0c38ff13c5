"""What the tests share beyond fixtures: deterministic records, an independent fake firmware,
the rPAM rig driven directly, and a third paper defined only here (``toy``).

``tests/`` is on the import path (``pythonpath`` in pyproject.toml), so tests import
these as ``support.<module>``; ``tests/conftest.py`` gives the common ones as fixtures.
"""
