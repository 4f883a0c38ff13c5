"""What most record types share: CSV through their table spec, no split, plain inspect lines.

A paper's record type (:class:`labcli.core.paper.RecordType`) may derive from
:class:`BaseRecordType` and give only what is its own: where its records live, the columns a
record holds, how one is checked and turned into a row (:meth:`~BaseRecordType.check`),
read back and tabled, and its CSV table spec (:mod:`labcli.core.tables`).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Iterable, Mapping
from typing import Any

from ..paper import Column
from ..report import records_line, settling_line, split_line
from ..tables import TableSpec, read_table, write_table


class BaseRecordType(ABC):
    """Defaults of :class:`labcli.core.paper.RecordType` (a subclass sets the attributes, names
    its ``table_spec`` and defines the four abstract methods; Python refuses to make one that
    lacks any)."""

    kind: str
    collection: str
    id_column: str
    noun: str
    plural: str
    splits: bool = False
    columns: tuple[Column, ...] = ()
    # Optional columns a later version added: a run file written before has no dataset for them, and
    # reads as though every record left them empty (nor does a record written to it carry them).
    added_columns: frozenset[str] = frozenset()
    # The store checks each record's row against the exchange table's bounds before writing it
    # (labcli.core.store.rows): what is stored is what may be exported.  A stream of estimates
    # opts out: its standard errors may be infinite, and it is written at the stream's rate.
    table_checked: bool = True

    # Read-only here, as the Protocol has them: a subclass sets a class attribute, or a
    # property when the value follows its instance (an rPAM run's experiment).
    @property
    def qualifier(self) -> str:
        return ""

    @property
    def signal(self) -> str:
        return ""

    @property
    @abstractmethod
    def table_spec(self) -> TableSpec:
        """The CSV table of these records (:mod:`labcli.core.tables`): a class attribute or a property."""

    @property
    def known_columns(self) -> frozenset[str]:
        return frozenset(self.table_spec.names)

    def count(self, n: int) -> str:
        """``3 points of the joint map``: a number of records in a sentence."""
        return f"{n} {self.noun if n == 1 else self.plural}{self.qualifier}"

    # -- what subclasses give
    @abstractmethod
    def check(self, record: Mapping[str, Any], label: str, run: Any) -> Mapping[str, Any]:
        """One record checked before it is written, as the row to store."""

    @abstractmethod
    def read(self, row: Mapping[str, Any]) -> dict[str, Any]:
        """A stored row turned back into a record."""

    @abstractmethod
    def table(self, run: Any, ids: list[int], cols: Mapping[str, Any]) -> Any:
        """The exchange table of the records ``ids``."""

    @abstractmethod
    def from_row(self, row: Mapping[str, Any], protocol: Any) -> dict[str, Any]:
        """A table row turned into a record."""

    # -- defaults
    def from_table(self, table: Any, protocol: Any) -> dict[str, Any]:
        """Every row through :meth:`from_row` and :meth:`check`, gathered into columns.

        Correct for any record type; a record type whose tables run to many rows gives a
        vectorised version (the trial table does)."""
        import numpy as np

        rows = []
        for row in table.to_dict("records"):
            record = self.from_row(row, protocol)
            rid = int(record[self.id_column])
            rows.append({**self.check(record, f"{self.noun} {rid}", None), self.id_column: rid})
        out: dict[str, Any] = {}
        for c in (Column(self.id_column, "1", kind="int"), *self.columns):
            if any(c.name in r for r in rows):
                if c.kind == "text":
                    out[c.name] = [str(r.get(c.name, "")) for r in rows]
                else:
                    out[c.name] = np.array(
                        [r[c.name] if c.name in r else np.full(c.shape, np.nan) for r in rows], dtype=c.dtype
                    ).reshape(len(rows), *c.shape)
        return out

    def import_split(self, table: Any) -> tuple[list[int], list[int]]:
        return [], []

    def read_csv(
        self,
        path: Any,
        *,
        id_range: tuple[int, int] | None = None,
        check: Callable[[dict[str, Any]], Iterable[tuple[str, str]]] | None = None,
    ) -> Any:
        return read_table(path, self.table_spec, id_range=id_range, check=check)

    def write_csv(self, table: Any, path: Any) -> None:
        write_table(table, path, self.table_spec)

    def summarise(self, run: Any, ids: list[int], cols: Mapping[str, Any]) -> dict[str, Any]:
        return {}

    def inspect_lines(self, summary: dict[str, Any]) -> list[str]:
        lines = [records_line(summary)]
        if self.splits:
            lines.append(split_line(summary))
        return lines + [settling_line(summary)]
