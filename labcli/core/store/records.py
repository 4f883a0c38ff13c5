"""What most record types share: CSV through their table spec, no split, plain inspect lines.

An experiment's record type (:class:`labcli.core.experiment.RecordType`) may derive from
:class:`BaseRecordType` and give only what is its own: where its records live, how one
is checked and written (:meth:`~BaseRecordType.check`), read back and tabled, and its
CSV table spec (:mod:`labcli.core.tables`).
"""

from __future__ import annotations

from typing import Any, Callable, Iterable, Mapping

from ..experiment import Stored
from ..report import records_line, settling_line, split_line
from ..tables import TableSpec, read_table, write_table


class BaseRecordType:
    """Defaults of :class:`labcli.core.experiment.RecordType` (a subclass sets the attributes)."""

    kind: str
    collection: str
    id_column: str
    noun: str
    plural: str
    qualifier: str = ""
    splits: bool = False
    table_spec: TableSpec

    @property
    def known_columns(self) -> frozenset[str]:
        return frozenset(self.table_spec.names)

    def count(self, n: int) -> str:
        """``3 points of the joint map``: a number of records in a sentence."""
        return f"{n} {self.noun if n == 1 else self.plural}{self.qualifier}"

    # -- what subclasses give
    def check(self, record: Mapping[str, Any], label: str, run: Any) -> Stored:
        raise NotImplementedError

    def read(self, group: Any) -> dict[str, Any]:
        raise NotImplementedError

    def table(self, run: Any, ids: list[int], groups: list[Any]) -> Any:
        raise NotImplementedError

    def from_row(self, row: Mapping[str, Any], protocol: Any, extra: dict[str, Any]) -> dict[str, Any]:
        raise NotImplementedError

    # -- defaults
    def import_split(self, rows: list[dict[str, Any]]) -> tuple[list[int], list[int]]:
        return [], []

    def read_csv(self, path: Any, *, id_range: tuple[int, int] | None = None,
                 check: Callable[[dict[str, Any]], Iterable[tuple[str, str]]] | None = None) -> Any:
        return read_table(path, self.table_spec, id_range=id_range, check=check)

    def write_csv(self, table: Any, path: Any) -> None:
        write_table(table, path, self.table_spec)

    def summarise(self, run: Any, ids: list[int], groups: list[Any]) -> dict[str, Any]:
        return {}

    def inspect_lines(self, summary: dict[str, Any]) -> list[str]:
        lines = [records_line(summary)]
        if self.splits:
            lines.append(split_line(summary))
        return lines + [settling_line(summary)]
