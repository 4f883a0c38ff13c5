"""Where a run file keeps its metadata (schema 3): a NeXus field where NeXus has a term for it,
an attribute of labcli's own collection where it has none.

::

    /entry                NXentry  @default
      title               "force run, protocol takuma2014"
      entry_identifier    the run's uid (uuid4)
      start_time          ISO 8601, microseconds, UTC offset
      program_name        "labcli"  @version  @configuration (the command line, file names only)
      user/               NXuser: name (the operator)
      instrument/         NXinstrument: name (the rig's device, its ID? reply)
      plot/               NXdata, /entry@default: every channel's calibrated values (frames x
                          channels) against device time and the channel's place in
                          raw@channels (hard links to raw/values and raw/time); up to schema 3
                          the first channel (a pressure) against time, the other channels in
                          its unit as @auxiliary_signals (links to raw/<channel>/value)
      labcli/             NXcollection  @schema @schema_version @metadata_checksum @kind @protocol
                          @host_name @firmware @port @channels @imported (0 or 1) @source;
        protocol (1,)     the protocol TOML, verbatim  @name @kind @file_name

NeXus validators (nxvalidate's nxinspect, punx) find each NeXus term where the standard puts it,
and labcli's own items in an ``NXcollection``, which may hold anything.  No NeXus application
definition describes a pneumatic-actuator run, so ``/entry/definition`` is left out rather than
naming one a validator does not know.  Schema 2 kept all of it as attributes of ``/entry`` and
the schema on the root; :func:`read_metadata` gives both in the same keys.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import h5py
import numpy as np

from ..files import stored_text
from .columns import FILTERS
from .h5 import plain, put, text

LABCLI = "labcli"  # the NXcollection of what NeXus has no term for
PROTOCOL = f"{LABCLI}/protocol"

# Key of RunFile.attrs -> (the NeXus field under /entry, the attribute of that field or None).
FIELDS: dict[str, tuple[str, str | None]] = {
    "title": ("title", None),
    "run_uid": ("entry_identifier", None),
    "start_time": ("start_time", None),
    "program_name": ("program_name", None),
    "program_version": ("program_name", "version"),
    "command_line": ("program_name", "configuration"),
    "operator": ("user/name", None),
    "device": ("instrument/name", None),
}
GROUPS = {"user": "NXuser", "instrument": "NXinstrument", LABCLI: "NXcollection"}


def home(f: h5py.File) -> Any:
    """The attributes that hold the schema and the metadata checksum: the root's up to schema 2,
    ``/entry/labcli``'s from schema 3."""
    if "schema" not in f.attrs and "entry" in f and LABCLI in f["entry"]:
        return f["entry"][LABCLI].attrs
    return f.attrs


def _stored(value: Any) -> Any:
    """A text as it is stored (:func:`~labcli.core.files.stored_text`), a list of texts each so."""
    if isinstance(value, str):
        return stored_text(value)
    if isinstance(value, (list, tuple)):
        return [stored_text(str(v)) for v in value]
    return value


def _text(parent: h5py.Group, name: str, value: str) -> h5py.Dataset:
    """A text as a one-element fixed-length UTF-8 dataset (chunked, so Fletcher32 covers it, as it does
    every dataset of a run file)."""
    data = stored_text(value).encode("utf-8")
    ds = parent.create_dataset(
        name, shape=(1,), dtype=h5py.string_dtype("utf-8", length=max(1, len(data))), chunks=(1,), **FILTERS
    )
    ds[0] = data
    return ds


def write_metadata(
    entry: h5py.Group,
    meta: Mapping[str, Any],
    own: Mapping[str, Any],
    protocol_text: str,
    protocol_attrs: Mapping[str, str],
) -> None:
    """The run's metadata into a new ``/entry``: ``meta`` (keys of :data:`FIELDS`) as NeXus fields,
    ``own`` as attributes of ``/entry/labcli``, and the protocol's text beside them."""
    for path, nx_class in GROUPS.items():
        put(entry.create_group(path), "NX_class", nx_class)
    for key, (path, attr) in FIELDS.items():
        if attr is None:
            _text(entry, path, str(meta[key]))
    for key, (path, attr) in FIELDS.items():
        if attr is not None:
            put(entry[path], attr, _stored(str(meta[key])))
    mine = entry[LABCLI]
    for key, value in own.items():
        put(mine, key, _stored(value))
    ds = _text(mine, "protocol", protocol_text)
    for k, v in protocol_attrs.items():
        put(ds, k, _stored(v))


def default_plot(entry: h5py.Group) -> None:
    """``/entry/plot``, the run's default plot (NeXus ``@default``): what a NeXus viewer
    (NeXpy, h5web, nexusformat's ``plot()``) draws when the file is opened: every frame of the
    run, window after window, against device time, each channel a column (``channel``: its
    place in ``raw@channels``).

    Its datasets are the raw log's own (hard links), so it costs no bytes and no write.  Not
    the channels' NXlog values: those are virtual datasets, which nexusformat (what nxinspect
    reads a file with) takes for a stack of files and sizes wrongly.  A record table is not
    plotted by default: its results are pairs (two angles, two force components), which a
    NeXus plot can only show as an image or with a ``"."`` axis that validators refuse.
    """
    raw = entry["raw"]
    channels = [text(c) for c in raw.attrs["channels"]]
    if not channels or "values" not in raw:
        return
    g = entry.create_group("plot")
    put(g, "NX_class", "NXdata")
    g["time"] = raw["time"]
    g["values"] = raw["values"]
    index = g.create_dataset("channel", data=np.arange(len(channels), dtype="<i8"), chunks=(len(channels),), **FILTERS)
    put(index, "units", "1")
    put(index, "long_name", "channel: " + ", ".join(channels))
    put(g, "signal", "values")
    put(g, "axes", ["time", "channel"])
    put(entry, "default", "plot")


def read_metadata(entry: h5py.Group) -> dict[str, Any]:
    """The run's metadata as plain values from schema 3's NeXus fields and ``/entry/labcli``, in the
    keys schema 2's attributes of ``/entry`` had.  A damaged field or attribute raises (OSError,
    KeyError, ValueError, ...): the caller says so in one sentence."""
    out = {k: plain(v) for k, v in entry[LABCLI].attrs.items()}
    out["imported"] = bool(out.get("imported", 0))
    for key, (path, attr) in FIELDS.items():
        ds = entry[path]
        v = ds[0] if attr is None else ds.attrs[attr]
        out[key] = v.decode("utf-8") if isinstance(v, bytes) else text(v)
    return out


def field_parts(f: h5py.File) -> list[bytes]:
    """The NeXus metadata fields' values, for the metadata checksum (a field is metadata as much as an
    attribute is); none in a schema-2 file."""
    entry = f.get("entry")
    if entry is None or LABCLI not in entry:
        return []
    parts = []
    for path, attr in FIELDS.values():
        if attr is None and path in entry:
            v = np.asarray(entry[path][0])
            parts.append(f"/entry/{path}:{v.dtype.str}:".encode() + v.tobytes())
    return parts
