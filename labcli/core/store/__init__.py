"""The HDF5 run file: :class:`RunFile` (crash-safe records of any paper) and its facets
(``run.records``, ``run.windows``, ``run.split``, ``run.models``, ``run.sessions``), and runs
built from tables (:func:`import_table`)."""

from .frames import WindowWriter
from .h5 import to_edge
from .importing import import_csv, import_table, storable_cells
from .layout import SCHEMA, SCHEMA_VERSION
from .runfile import RESUME_OR_FORCE, RunFile, load_table
from .split import Split, choose_split
from .view import MAX_ID

__all__ = [
    "MAX_ID",
    "RESUME_OR_FORCE",
    "SCHEMA",
    "SCHEMA_VERSION",
    "RunFile",
    "Split",
    "WindowWriter",
    "choose_split",
    "import_csv",
    "import_table",
    "load_table",
    "storable_cells",
    "to_edge",
]
