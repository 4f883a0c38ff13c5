"""The HDF5 run file: :class:`RunFile` (crash-safe records of any experiment), its split,
the models fitted on it, and runs built from tables (:func:`import_table`)."""

from .h5 import to_edge
from .importing import import_csv, import_table, storable_cells
from .runfile import MAX_ID, RESUME_OR_FORCE, SCHEMA, SCHEMA_VERSION, RunFile, load_table
from .split import choose_split

__all__ = ["MAX_ID", "RESUME_OR_FORCE", "SCHEMA", "SCHEMA_VERSION", "RunFile", "choose_split", "import_csv",
           "import_table", "load_table", "storable_cells", "to_edge"]
