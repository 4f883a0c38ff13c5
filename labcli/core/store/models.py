"""Models fitted on a run, kept in it: ``/models/<name>``, one JSON text each."""

from __future__ import annotations

import h5py

from ...errors import StoreError
from .h5 import text, text_dataset, utc_now


def store(f: h5py.File, name: str, json_text: str) -> None:
    """Store a model's parameters (JSON text) under ``/models/<name>``, replacing one of that name."""
    if not name or "/" in name or name.startswith("."):
        raise StoreError(f"model name {name!r} must be non-empty and contain no '/'.")
    if "models" not in f:
        f.create_group("models").attrs["NX_class"] = "NXcollection"
    g = f["models"]
    if name in g:
        del g[name]
    text_dataset(g, name, str(json_text), created=utc_now())


def read(f: h5py.File) -> dict[str, str]:
    """Model name -> JSON text, as recorded."""
    if "models" not in f:
        return {}
    return {name: text(ds[()]) for name, ds in f["models"].items()}


def names(f: h5py.File) -> list[str]:
    """The recorded models' names, sorted."""
    return sorted(f["models"]) if "models" in f else []
