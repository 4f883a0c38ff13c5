"""The HDF5 run file."""

from .runfile import *  # noqa: F401,F403
from .runfile import MAX_ID, RESUME_OR_FORCE, SCHEMA, SCHEMA_VERSION, RunFile, choose_split, import_table, storable_cells, to_edge  # noqa: F401
