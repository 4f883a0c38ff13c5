"""The seams between the paper-free core and one paper.

A *paper* is one paper's acquisition and analysis, plugged into the core through
the registry (:mod:`labcli.core.registry`).  The engine, the run file, the loader and the
commands talk to it only through the interfaces below, in the spirit of bluesky's
``protocols.py`` and pyserial's ``SerialBase``: a typing.Protocol says what an object
must offer, and anything that offers it plugs in.

* :class:`Paper`: the paper; its protocol kinds (plain data for the loader), the
  names of its shipped protocol files, its run kinds and their :class:`RecordType`, its
  simulated rigs and their own options, how it acquires (:class:`Acquisition`), its
  analyses (:class:`Analysis`) with the options each takes, the commands whose default
  protocol it ships, and its demo (:class:`Demo`).  Options are declared as data
  (:mod:`labcli.core.options`): a frozen dataclass per analysis and one for its rigs.
  Its module must import nothing heavy: the registry loads it to answer "which paper
  owns this kind", and heavy parts load on first use.
* :class:`ProtocolKind`: the sections a protocol of one kind holds, as plain-data key
  specs (:mod:`labcli.core.protocol` checks them), plus the hook that turns the checked
  sections into the paper's typed settings (``Protocol.settings``).
* :class:`RecordType`: what one record of a run kind holds (a trial, a push, a point) as
  declared :class:`Column` s, how it is checked and turned into a row of the run file's
  record table, read back, tabled as CSV, imported from a table and summarised by
  ``labcli inspect``.
* :class:`Acquisition`: one run being acquired: the protocol it records with, its session
  of steps (:mod:`labcli.core.steps`), its plan, and the rules of resuming it.
* :class:`RigAction`: what the experimenter does at the rig, which the simulated rig acts
  out in unattended runs.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Generator, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

if TYPE_CHECKING:
    from .tables import TableSpec

# --------------------------------------------------------------------------- protocol files


@dataclass(frozen=True)
class ChannelRoles:
    """What a ``[channels.NAME]`` table may name: the actuator of a pressure channel, the
    joint of an angle channel; a kind lists the roles its rig has, and each must be given."""

    actuators: tuple[str, ...] = ()
    joints: tuple[int, ...] = ()


@dataclass(frozen=True)
class ProtocolKind:
    """A protocol kind (``kind = "..."`` in the file) as plain data for the loader.

    ``sections`` maps a table name to ``(required | optional, spec name)``; a spec name is
    one of the core's (``device``, ``acquisition``, ``channel-map``, ``settling``), one of
    ``specs`` (key specs, see :mod:`labcli.core.protocol`), one of ``tables_of`` (a table
    of free names, each checked against another spec), or ``"open"`` (kept as written).
    ``extra_sections`` accepts tables not listed.  ``build(checked, checker, path)`` turns
    the checked tables into the paper's typed settings (``Protocol.settings``); it
    runs after the core's own sections, and reports through ``checker.fail(message)``.
    ``experiments`` maps ``--experiment`` choices to the run kinds they record, for a kind
    whose protocol holds several experiments; ``described_as`` names such a protocol in
    messages ("an rPAM protocol").
    """

    name: str
    sections: Mapping[str, tuple[str, str]]
    specs: Mapping[str, Any] = field(default_factory=dict)
    tables_of: Mapping[str, str] = field(default_factory=dict)
    extra_sections: bool = False
    channel_roles: ChannelRoles | None = None
    build: Callable[[dict[str, Any], Any, Path | None], Any] | None = None
    experiments: Mapping[str, str] = field(default_factory=dict)
    described_as: str = ""


# --------------------------------------------------------------------------- run files


@dataclass(frozen=True)
class Column:
    """One value every record of a kind holds: a column of its table in the run file.

    ``name`` names the dataset (``/entry/trials/P0``) and the key of a stored row;
    ``units`` is its ``@units`` attribute (``"MPa"``, ``"rad"``, ``"1"`` for ids and counts,
    ``""`` for text); ``shape`` is one record's value: ``()`` a number or a text, ``(4,)``
    four numbers, whose names are ``components``.  ``kind``: ``"float"``, ``"int"``,
    ``"text"`` (at most ``width`` bytes of UTF-8; longer is refused when written).
    ``optional`` values may be missing (NaN, or ``""`` for text); the others must be
    finite.  (The run file's own columns also use ``kind`` ``"uint"`` and ``"flag"``.)  ``bounds`` is the range a stored value can physically take: a value read back
    outside it marks the record damaged (a changed file), named in a sentence with ``what``.
    """

    name: str
    units: str
    shape: tuple[int, ...] = ()
    kind: str = "float"
    width: int = 0
    components: tuple[str, ...] = ()
    bounds: tuple[float, float] | None = None
    optional: bool = False
    what: str = ""

    @property
    def dtype(self) -> Any:
        """The numpy dtype the column is stored as."""
        return _stored_dtype(self.kind, self.width)


@functools.cache
def _stored_dtype(kind: str, width: int) -> Any:
    # Asked for every column of every row written: made once per kind and width.
    import numpy as np

    return {"float": np.dtype("<f8"), "int": np.dtype("<i8"), "uint": np.dtype("<u8"), "flag": np.dtype("i1")}.get(
        kind
    ) or np.dtype(f"S{max(1, width)}")


@runtime_checkable
class RecordType(Protocol):
    """One record kind of a run: where it lives, what it holds, how it is tabled.

    The run file (:class:`labcli.core.store.RunFile`) keeps the records of a run as the rows
    of one table (``/entry/<collection>``): the columns every record has (the id, times,
    settling, raw-window references, checksum), written by the run file itself, and the
    record type's :attr:`columns`.  The record type turns a record into its row
    (:meth:`check`) and rows back into records and tables; rows come as a mapping of column
    name to value (one record) or to an array over the records (``cols``).
    """

    @property
    def kind(self) -> str:
        """The run kind, e.g. ``"force"``."""

    @property
    def collection(self) -> str:
        """The table records live in, e.g. ``"trials"``."""

    @property
    def id_column(self) -> str:
        """The id column, e.g. ``"trial"``."""

    @property
    def noun(self) -> str:
        """``"trial"`` (for sentences)."""

    @property
    def plural(self) -> str:
        """``"trials"``."""

    @property
    def qualifier(self) -> str:
        """Appended to counts in sentences, e.g. ``" of the joint map"`` (``""`` for none)."""

    @property
    def splits(self) -> bool:
        """Whether records join the run's fit/validation split."""

    @property
    def known_columns(self) -> frozenset[str]:
        """Table columns the record type stores (others are kept as extras)."""

    @property
    def columns(self) -> tuple[Column, ...]:
        """What one record holds besides what every record has."""

    @property
    def signal(self) -> str:
        """The column a NeXus reader plots (``@signal`` of the record table)."""

    @property
    def table_spec(self) -> TableSpec:
        """The CSV exchange table's columns, units and ranges (export, import, the sidecar)."""

    def count(self, n: int) -> str:
        """``3 points of the joint map``: a number of these records in a sentence."""

    def check(self, record: Mapping[str, Any], label: str, run: Any) -> Mapping[str, Any]:
        """Check a record before anything touches the file (StoreError); its row: column -> value.

        Optional columns may be left out (stored missing)."""

    def read(self, row: Mapping[str, Any]) -> dict[str, Any]:
        """The record-specific part of a stored row, as the writer gave it (SI)."""

    def table(self, run: Any, ids: list[int], cols: Mapping[str, Any]) -> Any:
        """The CSV exchange table (DataFrame) of these records, without the extra columns.

        ``cols`` maps each of :attr:`columns` to its values over the records (an array whose
        first axis follows ``ids``)."""

    def from_row(self, row: Mapping[str, Any], protocol: Any) -> dict[str, Any]:
        """One table row (as read by :meth:`read_csv`) as the record :meth:`check` takes.

        The importer adds what every imported record carries (``accepted``, ``extra``)."""

    def from_table(self, table: Any, protocol: Any) -> dict[str, Any]:
        """A whole table (DataFrame, as read by :meth:`read_csv`) as columns: name -> array
        over its rows, the id column included (what :meth:`RunFile.append` takes)."""

    def import_split(self, table: Any) -> tuple[list[int], list[int]]:
        """Fit and validation ids named by an imported table (DataFrame; empty lists: no split)."""

    def read_csv(
        self,
        path: Any,
        *,
        id_range: tuple[int, int] | None = None,
        check: Callable[[dict[str, Any]], Iterable[tuple[str, str]]] | None = None,
    ) -> Any:
        """Read and check a CSV table of these records (:class:`labcli.core.tables.TableError`)."""

    def write_csv(self, table: Any, path: Any) -> None:
        """Write the table as CSV, atomically."""

    def summarise(self, run: Any, ids: list[int], cols: Mapping[str, Any]) -> dict[str, Any]:
        """Keys this record type adds to ``RunFile.summary()`` (``baseline_drift``, ...)."""

    def inspect_lines(self, summary: dict[str, Any]) -> list[str]:
        """The record-specific lines of ``labcli inspect`` (records, split, settling, ...)."""


# --------------------------------------------------------------------------- simulated rigs


@runtime_checkable
class SimulatedRig(Protocol):
    """A paper's simulated rig, as the firmware model, the fault injector, the pty server and the
    ``sim://`` handler use it (:mod:`labcli.core.sim`): named channels sampled on a clock that
    runs only as it is read or advanced.  Operator actions are the rig's own methods."""

    @property
    def channels(self) -> Sequence[str]:
        """The sensor channels, in the order of every frame's values."""

    @property
    def device(self) -> str:
        """The device name the firmware reports (``ID?``)."""

    @property
    def firmware(self) -> str:
        """The firmware version the device reports."""

    @property
    def time_s(self) -> float:
        """The rig's simulated time, s."""

    def samples(self, n: int, rate_hz: float) -> tuple[Any, Any]:
        """``n`` ADC samples at ``rate_hz``: ``(t_us int64 (n,), counts int64 (n, channels))``."""

    def advance(self, seconds: float) -> None:
        """Let ``seconds`` of simulated time pass without sampling."""

    def advance_to(self, time_s: float) -> None:
        """Let simulated time run up to ``time_s`` (no-op if already past it)."""


# --------------------------------------------------------------------------- acquisition


class RigAction(Protocol):
    """What the experimenter does at the rig; the simulated rig acts it out unattended."""

    def act_on(self, rig: Any) -> None:
        """Do it on the simulated rig (ValueError with a sentence when it cannot)."""


@dataclass(frozen=True)
class AcquireOptions:
    """What ``labcli acquire`` was asked for, for the paper to judge.

    ``experiment``: the ``--experiment`` choice of a protocol holding several;
    ``plan``/``no_plan``: a plan file, or typed loads; ``resume``: the run being continued
    (None for a new run); ``captures``: the ``--captures`` of each load (None: the protocol's).
    """

    path: str
    plan: str | Path | None = None
    no_plan: bool = False
    experiment: str | None = None
    unattended: bool = False
    resume: Any = None  # the open RunFile being resumed
    captures: int | None = None


Session = Generator[Any, Any, None]


class Acquisition(Protocol):
    """One run being acquired, as the paper plans it."""

    protocol: Any  # the protocol the run records with (calibration, channels, settling, ...)
    kind: str  # the run kind
    plan: Any  # the plan table stored in a new run (a DataFrame or None)

    def session(self, completed: Sequence[int]) -> Session:
        """The steps of the run, skipping the record ids already ``completed``."""

    def already_done(self, run: Any, path: str) -> str | None:
        """On resuming: the sentence to end with when nothing is left to record (None: go on).

        May finish the run's bookkeeping first (the split of a finished plan)."""


# --------------------------------------------------------------------------- analyses


@dataclass(frozen=True)
class Analysis:
    """One analysis a command runs: ``run(inputs, options, ...) -> result``, ``show(result, as_json=...)``.

    ``run`` is a plain library function (raises :class:`~labcli.errors.LabcliError`): its
    first arguments are the command's (the input path; the protocol for ``optimize``), then
    the options object of the paper's declaration for that command
    (``Paper.analysis_options[command]``), then the command's own keywords (``fit``:
    ``output``, ``protocol``; ``validate`` and ``classify``: ``protocol``).  ``show``
    prints the result (the paper's report module).
    """

    run: Callable[..., Any]
    show: Callable[..., None]


@dataclass(frozen=True)
class Demo:
    """The paper on the simulated rig: ``run(outdir, seed=, force=, progress=) -> result``."""

    stages: tuple[str, ...]
    run: Callable[..., Any]
    show: Callable[[Any], None]


# --------------------------------------------------------------------------- the paper


@runtime_checkable
class Paper(Protocol):
    """One paper, as the core sees it.  Attributes are plain data; methods load lazily."""

    name: str  # e.g. "takuma2014"
    title: str
    paper: str  # the paper, as cited
    protocol_kinds: Mapping[str, ProtocolKind]
    shipped_protocols: tuple[str, ...]  # file stems in protocols/ this paper owns
    run_kinds: tuple[str, ...]
    untagged_run_kind: str | None  # the kind of a run file naming none (early schema-1 files; one paper at most)
    sim_modes: tuple[str, ...]  # ``sim://?mode=`` values this paper's rigs answer to
    default_sim_mode: str | None  # the rig ``sim://`` gives without mode= (one paper at most)
    sim_options: type | None  # its rigs' own options: a dataclass of labcli.core.options fields (None: none)
    analysis_options: Mapping[str, type]  # command ("fit", ...) -> the options its analysis takes (a dataclass)
    default_protocols: Mapping[str, str]  # command -> the shipped protocol it uses when nothing names one
    demo_protocol: str | None  # ``labcli demo --protocol NAME`` runs this paper's demo

    def record_type(self, run_kind: str) -> RecordType:
        """The record type of one of :attr:`run_kinds`."""

    def make_rig(
        self, mode: str, *, seed: int, noise: float, drift: float | None, tau_s: float, options: Any
    ) -> SimulatedRig:
        """A simulated rig for one of :attr:`sim_modes` (see :mod:`labcli.core.sim`); ``options``
        is an object of :attr:`sim_options` (None when the paper declares none); ``drift`` None:
        the rig's own default."""

    def run_protocol(
        self, protocol: Any, choice: str | None, *, stored_kind: str | None = None, run_path: str = ""
    ) -> Any:
        """The protocol as a run records it (its ``kind`` the run kind), ``choice`` being
        the ``--experiment`` option; ``stored_kind`` is the kind of a run being resumed."""

    def import_protocol(self, protocol: Any, choice: str | None, name: str) -> Any:
        """As :meth:`run_protocol`, for ``labcli import`` (its own sentences)."""

    def acquisition(self, protocol: Any, options: AcquireOptions) -> Acquisition:
        """Plan one run of ``protocol`` (from :meth:`run_protocol`).

        A paper whose runs of some kinds take each load several times (``--captures``,
        ``acquisition.captures_per_load``) lists those run kinds in an attribute ``capture_kinds``
        (a tuple, optional); the core refuses more than one capture a load for any other kind
        (:func:`labcli.core.acquisition.check_captures`), in the words of an optional attribute
        ``single_captures``: run kind -> (the unit such a run takes once, the clause saying why)."""

    def analysis(self, name: str) -> Analysis | None:
        """The analysis of command ``name`` (one of :attr:`analysis_options`, or ``export-model``), or None.

        A paper whose fit writes model files lists their ``schema`` in an attribute
        ``model_schemas`` (a tuple, optional), so that a command given only a model file finds it
        (:func:`labcli.core.dispatch.for_model_file`)."""

    def demo(self) -> Demo | None:
        """The paper's demo on the simulated rig, or None."""
