"""The HDF5 run file: one file per run, every trial written whole and crash-safe.

Layout (schema ``labcli-run``, version 1).  SI inside: pressures MPa gauge,
angles rad, forces N, lengths m, masses kg, times s.  Every dataset carries a
``units`` attribute (``""`` for text, ``"1"`` for ids and counters); every
group an ``NX_class`` attribute in the NeXus style::

    /                               NX_class=NXentry
      @schema           "labcli-run"
      @schema_version   1
      @labcli_version   "0.1.0"
      @kind             "force" | "push" | "rpam-stretch" | "rpam-joint"
      @protocol         protocol name, e.g. "takuma2014"
      @device @firmware from the rig's ID? reply ("" for imported runs)
      @port             serial port or URL ("" for imported runs)
      @channels         channel names, in data-line order
      @operator         who ran it
      @started          ISO 8601 UTC, e.g. "2024-05-01T09:30:00Z"
      @imported         True when built from a CSV table (no raw windows)
      @source           the imported CSV's file name ("" otherwise)
      protocol          the protocol TOML, verbatim (string; @name @kind @path)
      calibration/      NXcollection: gain (k,) SI/count, offset (k,) SI, @units per channel
      plan/             NXcollection, only when a plan was given: one dataset per plan
                        column (trial, set, mass_g, direction_deg, ...), table units
      trials/           NXcollection, force runs
        000012/         NXcollection, one trial (id zero-padded to 6 digits)
          @trial @order (recording order, 0-based) @started @ended (ISO 8601 UTC)
          @settle_time_s @settle_criterion @accepted ("auto" | "timeout" | "operator"
                        | "imported") for the loaded window
          @plan_set @plan_mass_g @plan_direction_deg  the plan row, when there was one
          P0 (4,) MPa   baseline pressures P_L1,P_R1,P_L2,P_R2 (@channels)
          P  (4,) MPa   pressures under the load
          theta (2,) rad  joint deflections under the load (joint 1, joint 2)
          pot0 (2,) rad   potentiometer angles of the baseline posture (optional)
          F (2,) N      applied force Fx, Fy at the contact point
          mass () kg    pulley weight (NaN when not a pulley load)
          direction () rad  pulley direction, counter-clockwise from +x (NaN if unknown)
          extra/        columns of an imported table that labcli does not know
          baseline/     NXlog, the unloaded window; loaded/ NXlog, the loaded window:
            time (n,) s float64     device time, unwrapped
            counts (n,k) int32      values as sent (float64 if the device sends decimals)
            values (n,k) float64    calibrated SI values, @units "MPa,...,rad"
            seq (n,) uint32         frame counter as sent
            @settled @settle_time_s @waited_s @pressure_spread_MPa
            @angle_spread_rad @criterion @accepted
          @complete     True, written last (see below)
        000012.1/       a later attempt at trial 12, when a kill left 000012
                        unfinished (which stays, ignored)
      pushes/           NXcollection, push runs
        000003/         @push @order @object @category, R () m, d () m,
                        phi () rad (NaN unknown), true_stiffness () N/m (NaN unless
                        simulated), P0, P, theta and pot0 (optional), extra/,
                        baseline/, loaded/, the trial attributes, @complete as above
      points/           NXcollection, rPAM runs (kinds rpam-stretch, rpam-joint)
        000007/         @point @experiment ("stretch" | "joint") @order, the set values
                        @plan_mass_g @plan_P_A_kPa @plan_P_B_kPa; P (2,) MPa (P_A, P_B);
                        stretch: mass () kg, L () m, lambda () 1; joint map: alpha () rad
                        (deflection from the vented baseline), P0 (2,) MPa, pot0 () rad,
                        L () m; baseline/ (joint map), loaded/, extra/ (imported), @complete as above
      index (16384,)    object references to the record groups in recording order,
                        written in place (storage allocated at creation): a second
                        way to every complete record if a crash damages a link list
      split/            NXcollection: fit (m,) and validation (v,) trial ids
                        @strategy ("sequential" | "random" | "plan" | "imported" | ...)
                        @seed (-1 when none) @created
      models/           NXcollection: one string dataset of JSON per fitted model, @created

Crash safety.  A trial group is created with ``@complete = False``; its
datasets and attributes are written, the file is flushed and fsynced, and only
then is ``@complete`` set to True (in place) and the file flushed and fsynced
again.  Readers count only complete groups.  An incomplete one (a crash's
leftover) is never removed: the next attempt at its id is written beside it as
``000012.1``, because a removal frees blocks at the end of the file and HDF5
shrinks the file at the next flush, which a kill at that moment turns into a
file that no longer opens.  Nothing is ever deleted during a session.  The root's groups all exist from creation,
so the root's link list never changes afterwards; each record's reference
goes into ``/index`` before the first fsync.  The file uses HDF5's default format bounds
(not ``libver='latest'``, not SWMR: after a kill -9 those refuse to open
without ``h5clear``) with the file-space strategy "none", so space freed
during a session is never reused and structures already on disk are never
overwritten by new data.  A new file is built as ``RUN.h5.creating`` and
renamed once its metadata is on disk, so a kill during creation leaves no
half-made run and ``force=True`` keeps the old file until the new one exists.

Records.  :class:`TrialRecord` and :class:`PushRecord` (plain dicts) are what
the acquisition session hands to :meth:`RunFile.write_trial` and
:meth:`RunFile.write_push`.

Tables.  :meth:`RunFile.trial_table` and :meth:`RunFile.push_table` give the
CSV exchange tables (``table-formats.md``): MPa, N, m, and degrees and grams
rounded to 12 significant digits (:func:`to_edge`), which makes
table -> run file -> table exact; :meth:`RunFile.point_table` does the same for
rPAM runs.  HDF5 strings end at a NUL, so text holding one is refused before any
file is made (:func:`storable_cells`) rather than stored cut short.
"""

from __future__ import annotations

import datetime as _dt
import functools
import math
import os
from typing import Any, Iterable, Mapping, Sequence, TypedDict

import h5py
import numpy as np

from ...errors import ConfigError, LabcliError, StoreError
from ..registry import record_type

SCHEMA = "labcli-run"
SCHEMA_VERSION = 1

PRESSURE_NAMES = ("P_L1", "P_R1", "P_L2", "P_R2")
BASELINE_COLUMNS = ("P_L10", "P_R10", "P_L20", "P_R20")
TRIAL_COLUMNS = (
    "trial", "set", *BASELINE_COLUMNS, *PRESSURE_NAMES,
    "theta1_deg", "theta2_deg", "Fx_N", "Fy_N",
)
TRIAL_OPTIONAL_COLUMNS = ("mass_g", "direction_deg")
PUSH_COLUMNS = ("push", "object", "R_m", "d_m", "phi_deg", *BASELINE_COLUMNS, *PRESSURE_NAMES, "category")
PUSH_OPTIONAL_COLUMNS = ("true_stiffness_N_per_m",)
ACCEPTED = ("auto", "timeout", "operator", "imported")
MAX_ID = 999_999
INDEX_SLOTS = 16_384  # records reachable through /index; later ones by name only
_RPAM_EXPERIMENTS = {"rpam-stretch": "stretch", "rpam-joint": "joint"}
_EDGE_DIGITS = 12
# What to do about a run file that already exists where a new run would go.
RESUME_OR_FORCE = "continue it with --resume, or pass --force to overwrite it"

_WINDOW_GROUPS = {"baseline": "baseline", "load": "loaded", "loaded": "loaded"}


# --------------------------------------------------------------------------- records


class RawWindow(TypedDict, total=False):
    """One capture window as received (``labcli.experiments.takuma2014.session.Window.as_dict()``).

    ``seq`` (n,) frame counters, ``t_us`` (n,) device clock (wraps at 2**32),
    ``counts`` (n, k) values as sent, ``si`` (n, k) calibrated SI values;
    ``t_s`` (n,) unwrapped device time in s, optional (derived from ``t_us``).
    """

    seq: Any
    t_us: Any
    counts: Any
    si: Any
    t_s: Any


class SettleInfo(TypedDict, total=False):
    """How a window's equilibrium was reached (``labcli.core.settle.SettleReport.as_dict()``)."""

    settled: bool  # False: timed out and accepted
    settle_time_s: float
    waited_s: float
    pressure_spread_MPa: float
    angle_spread_rad: float
    criterion: str
    accepted: str  # overrides the auto/timeout reading of ``settled`` (e.g. "operator")


class _TrialRequired(TypedDict):
    trial: int
    P0_MPa: Any  # (4,) P_L1, P_R1, P_L2, P_R2 before the load
    P_MPa: Any  # (4,) under the load
    theta_rad: Any  # (2,) joint deflections under the load
    force_N: Any  # (2,) Fx, Fy at the contact point


class TrialRecord(_TrialRequired, total=False):
    """What :meth:`RunFile.write_trial` takes: one force/angle trial, SI.

    Optional keys: ``set`` (the plan's set), ``mass_kg``, ``direction_rad``
    (NaN if not a pulley load), ``pot0_rad`` (2,), ``settle`` (``{"baseline":
    SettleInfo, "load": SettleInfo}``), ``raw`` (``{"baseline": RawWindow,
    "load": RawWindow}``), ``started``/``ended`` (ISO 8601 UTC; ``ended``
    defaults to the write time), ``plan`` (the plan row: ``mass_g``,
    ``direction_deg``, ``set``), ``extra`` (other table columns, name -> value).
    """

    set: str
    mass_kg: float
    direction_rad: float
    pot0_rad: Any
    settle: dict
    raw: dict
    started: str
    ended: str
    plan: dict
    extra: dict


class _PushRequired(TypedDict):
    push: int
    object: str
    R_m: float
    d_m: float
    P0_MPa: Any
    P_MPa: Any


class PushRecord(_PushRequired, total=False):
    """What :meth:`RunFile.write_push` takes: one object push, SI.

    Optional keys: ``phi_rad`` (None or NaN when unknown), ``category``,
    ``true_stiffness_N_per_m`` (simulated objects), and ``settle``, ``raw``,
    ``started``, ``ended``, ``extra`` as in :class:`TrialRecord`.
    """

    phi_rad: float | None
    category: str
    true_stiffness_N_per_m: float | None
    settle: dict
    raw: dict
    started: str
    ended: str
    extra: dict


# --------------------------------------------------------------------------- record checks and conversions


def utc_now() -> str:
    """The current time as ISO 8601 UTC with a Z suffix, to the second."""
    return _dt.datetime.now(_dt.timezone.utc).replace(microsecond=0).isoformat().replace("+00:00", "Z")


def to_edge(values: Any) -> np.ndarray:
    """Round converted table values (deg, g) to 12 significant digits.

    A value typed in degrees or grams, stored in rad or kg and converted back,
    lands within a few ulp of what was typed; rounding at the edge makes
    table -> run file -> table exact while keeping far more digits than any sensor.
    """
    arr = np.asarray(values, dtype=np.float64)
    return np.array([float(f"{v:.{_EDGE_DIGITS}g}") for v in arr.ravel()], dtype=np.float64).reshape(arr.shape)


def _str(v: Any) -> str:
    if isinstance(v, bytes):
        return v.decode("utf-8")
    return str(v)


def _plain(v: Any) -> Any:
    """HDF5 attribute value -> plain Python value."""
    if isinstance(v, bytes):
        return v.decode("utf-8")
    if isinstance(v, np.ndarray):
        return [_plain(x) for x in v.tolist()]
    if isinstance(v, np.bool_):
        return bool(v)
    if isinstance(v, np.integer):
        return int(v)
    if isinstance(v, np.floating):
        return float(v)
    return v


def _vector(record: Mapping, key: str, n: int, what: str, label: str, *, finite: bool = True) -> np.ndarray:
    if key not in record:
        raise StoreError(f"{label} record lacks '{key}' ({what}).")
    try:
        arr = np.asarray(record[key], dtype=np.float64)
    except (TypeError, ValueError):
        raise StoreError(f"{label} record: '{key}' must be numbers ({what}).") from None
    if arr.shape != (n,):
        raise StoreError(f"{label} record: '{key}' must hold {n} values ({what}), got shape {arr.shape}.")
    if finite and not np.all(np.isfinite(arr)):
        raise StoreError(f"{label} record: '{key}' holds a value that is not finite ({what}).")
    return arr


def _scalar(record: Mapping, key: str, label: str, *, default: float = math.nan) -> float:
    v = record.get(key, default)
    if v is None:
        return math.nan
    try:
        return float(v)
    except (TypeError, ValueError):
        raise StoreError(f"{label} record: '{key}' must be a number, got {v!r}.") from None


# Raw windows of a few hundred samples a channel are most of a run's data; byte-shuffled
# gzip shrinks the large ones about fourfold at a cost far below the fsync each trial pays.
# Below about a thousand values a chunk index costs more than it saves: those stay contiguous.
_RAW_COMPRESSION = {"compression": "gzip", "compression_opts": 4, "shuffle": True}
_RAW_MIN_VALUES = 1000


def _dataset(g: h5py.Group, key: str, data: Any, units: str, *, raw: bool = False,
             **attrs: Any) -> h5py.Dataset:
    arr = np.asarray(data)
    opts = _RAW_COMPRESSION if raw and arr.size >= _RAW_MIN_VALUES else {}
    ds = g.create_dataset(key, data=arr, **opts)
    ds.attrs["units"] = units
    for k, v in attrs.items():
        ds.attrs[k] = v
    return ds


def _text_dataset(g: h5py.Group, key: str, text: str, **attrs: Any) -> h5py.Dataset:
    ds = g.create_dataset(key, data=text, dtype=h5py.string_dtype("utf-8"))
    ds.attrs["units"] = ""
    for k, v in attrs.items():
        ds.attrs[k] = v
    return ds


def _column_units(name: str) -> str:
    for suffix, units in (("_g", "g"), ("_deg", "deg"), ("_N_per_m", "N/m"), ("_N", "N"), ("_m", "m"),
                          ("_MPa", "MPa"), ("_s", "s")):
        if name.endswith(suffix):
            return units
    if name in PRESSURE_NAMES or name in BASELINE_COLUMNS:
        return "MPa"
    if name in ("trial", "push"):
        return "1"
    return ""


def _write_columns(g: h5py.Group, columns: Mapping[str, Any], order: Sequence[str]) -> None:
    """Store table columns as one dataset each (text or float64/int64)."""
    g.attrs["columns"] = list(order)
    for name in order:
        values = list(columns[name])
        if values and all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) for v in values):
            _dataset(g, name, np.asarray(values, dtype=np.int64), _column_units(name))
            continue
        if not any(isinstance(v, str) for v in values):
            try:
                arr = np.asarray([math.nan if v is None else float(v) for v in values], dtype=np.float64)
            except (TypeError, ValueError):
                pass
            else:
                _dataset(g, name, arr, _column_units(name))
                continue
        texts = ["" if v is None or (isinstance(v, float) and math.isnan(v)) else str(v) for v in values]
        ds = g.create_dataset(name, data=np.array(texts, dtype=object), dtype=h5py.string_dtype("utf-8"))
        ds.attrs["units"] = ""


def _read_columns(g: h5py.Group) -> dict[str, list]:
    out: dict[str, list] = {}
    for name in [_str(c) for c in g.attrs.get("columns", list(g))]:
        ds = g[name]
        if h5py.check_string_dtype(ds.dtype) is not None:
            out[name] = [_str(v) for v in ds[()]]
        else:
            out[name] = ds[()].tolist()
    return out


def _unwrap_us(t_us: np.ndarray) -> np.ndarray:
    """Device time in s from a 32-bit microsecond clock that wraps."""
    t = np.asarray(t_us, dtype=np.int64)
    if t.size == 0:
        return np.zeros(0, dtype=np.float64)
    steps = np.diff(t)
    wraps = np.concatenate([[0], np.cumsum(steps < 0)])
    return (t + wraps * (1 << 32)) * 1e-6


def _window_arrays(raw: Mapping, k: int, label: str, which: str) -> dict[str, np.ndarray]:
    missing = [key for key in ("seq", "counts", "si") if key not in raw]
    if "t_s" not in raw and "t_us" not in raw:
        missing.append("t_us")
    if missing:
        raise StoreError(f"{label} record: the {which} window lacks {', '.join(missing)}.")
    seq = np.asarray(raw["seq"])
    n = seq.shape[0] if seq.ndim == 1 else -1
    counts = np.asarray(raw["counts"])
    si = np.asarray(raw["si"], dtype=np.float64)
    time = np.asarray(raw["t_s"], dtype=np.float64) if "t_s" in raw else _unwrap_us(raw["t_us"])
    if n < 0 or counts.shape != (n, k) or si.shape != (n, k) or time.shape != (n,):
        raise StoreError(
            f"{label} record: the {which} window must hold n frames of {k} channels "
            f"(seq (n,), counts (n,{k}), si (n,{k})), got seq {seq.shape}, counts {counts.shape}, si {si.shape}."
        )
    counts_f = counts.astype(np.float64)
    if np.all(np.isfinite(counts_f)) and np.all(counts_f == np.rint(counts_f)) and (
        counts_f.size == 0 or np.abs(counts_f).max() < 2**31
    ):
        counts_out = counts_f.astype(np.int32)
    else:
        counts_out = counts_f  # decimals as sent: kept exactly rather than rounded
    return {"time": time, "counts": counts_out, "values": si, "seq": (seq.astype(np.int64) % (1 << 32)).astype(np.uint32)}


def _settle_attrs(info: Mapping | None) -> dict[str, Any]:
    if not info:
        return {}
    out: dict[str, Any] = {}
    for key in ("settle_time_s", "waited_s", "pressure_spread_MPa", "angle_spread_rad"):
        if key in info and info[key] is not None:
            out[key] = float(info[key])
    if "criterion" in info:
        out["criterion"] = str(info["criterion"])
    if "settled" in info:
        out["settled"] = bool(info["settled"])
    accepted = info.get("accepted")
    if accepted is None and "settled" in info:
        accepted = "auto" if info["settled"] else "timeout"
    if accepted is not None:
        if accepted not in ACCEPTED:
            raise StoreError(f"settle 'accepted' must be one of {', '.join(ACCEPTED)}, got {accepted!r}.")
        out["accepted"] = accepted
    return out


Window = tuple[str, dict[str, np.ndarray], dict[str, Any]]  # group name, arrays, settle attributes


def _checked_common(record: Mapping, k: int, label: str) -> tuple[dict[str, Any], list[Window]]:
    """The record's settle attributes and raw windows, checked and converted before anything touches the file."""
    settle = record.get("settle") or {}
    load = _settle_attrs(settle.get("load") or settle.get("loaded"))
    accepted = str(record.get("accepted", load.get("accepted", "auto" if record.get("raw") else "imported")))
    if accepted not in ACCEPTED:
        raise StoreError(f"{label} record: 'accepted' must be one of {', '.join(ACCEPTED)}, got {accepted!r}.")
    attrs = {"settle_time_s": float(load.get("settle_time_s", math.nan)),
             "settle_criterion": str(load.get("criterion", "")), "accepted": accepted}
    windows: list[Window] = []
    for key, raw_w in (record.get("raw") or {}).items():
        if key not in _WINDOW_GROUPS:
            raise StoreError(f"{label} record: unknown window {key!r} in 'raw' (use baseline and load).")
        name = _WINDOW_GROUPS[key]
        if any(name == w[0] for w in windows):
            raise StoreError(f"{label} record: 'raw' gives the {name} window twice.")
        windows.append((name, _window_arrays(raw_w, k, label, name),
                        _settle_attrs(settle.get(key) or settle.get(name))))
    return attrs, windows


def _calibration_arrays(protocol: Any, k: int) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """Per-channel gain and offset of the protocol's (linear) calibration."""
    cal = getattr(protocol, "calibration", None)
    units = [str(u) for u in getattr(cal, "units", ())] if cal is not None else []
    if len(units) != k:
        units = [""] * k
    if cal is None or not hasattr(cal, "to_si"):
        return np.full(k, math.nan), np.full(k, math.nan), units
    probe = np.array([[0.0] * k, [1000.0] * k])
    si = np.asarray(cal.to_si(probe), dtype=np.float64)
    return (si[1] - si[0]) / 1000.0, si[0].copy(), units


# --------------------------------------------------------------------------- split


def choose_split(ids: Sequence[int], n_fit: int, n_validation: int, strategy: str = "sequential",
                 seed: int | None = None) -> tuple[list[int], list[int]]:
    """Pick fit and validation ids from ``ids`` (in recording order).

    ``sequential``: the first ``n_fit`` ids fit, the next ``n_validation``
    validate (the paper's 90 + 18); ``random``: a permutation seeded by ``seed``
    (0 when None), each set listed in recording order.
    """
    if n_fit < 1 or n_validation < 0:
        raise ConfigError(f"the fit set needs at least 1 trial and the validation set 0 or more, got {n_fit} and {n_validation}.")
    need = n_fit + n_validation
    if need > len(ids):
        raise ConfigError(
            f"the run has {len(ids)} completed trials, fewer than the {need} asked for "
            f"({n_fit} fit + {n_validation} validation)."
        )
    ids = [int(i) for i in ids]
    if strategy == "sequential":
        return ids[:n_fit], ids[n_fit:need]
    if strategy == "random":
        rng = np.random.default_rng(0 if seed is None else seed)
        picked = [ids[i] for i in rng.permutation(len(ids))[:need]]
        rank = {t: i for i, t in enumerate(ids)}
        return sorted(picked[:n_fit], key=rank.__getitem__), sorted(picked[n_fit:], key=rank.__getitem__)
    raise ConfigError(f"unknown split strategy {strategy!r}; use sequential or random.")


# --------------------------------------------------------------------------- the run file


class RunFile:
    """An open run file.  Use as a context manager; writes are crash-safe per trial.

    >>> with RunFile.create("run.h5", protocol=proto, device_info=dev.info,
    ...                     port="sim://", operator="ada") as run:   # doctest: +SKIP
    ...     run.write_trial(record)
    """

    def __init__(self, h5: h5py.File, path: str) -> None:
        self._f = h5
        self.path = path
        self._channels = tuple(_str(c) for c in h5.attrs.get("channels", ()))
        # fsync each record (crash safety); a file built whole under a temporary
        # name (import) turns it off and is synced once when closed.
        self.sync_each_record = True
        # (collection, id) -> (recording order, object reference) of every complete
        # record.  Scanned once: the file is locked, so only this object adds records.
        self._unreadable: set[str] = set()  # collections whose link list the scan could not read
        complete, self._incomplete = self._scan()
        self._index: dict[tuple[str, int], tuple[int, Any]] = {
            (c, rid): (order, ref) for c, order, rid, ref in complete
        }
        self._order = max((order for order, _ in self._index.values()), default=-1) + 1

    # ----------------------------------------------------------- open / create

    @classmethod
    def create(
        cls,
        path: str | os.PathLike,
        *,
        protocol: Any,
        device_info: Any = None,
        port: str = "",
        operator: str = "",
        plan: Any = None,
        force: bool = False,
        imported: bool = False,
        source: str = "",
        started: str | None = None,
        exists_hint: str = RESUME_OR_FORCE,
        kind: str | None = None,
    ) -> "RunFile":
        """Create a new run file for ``protocol`` (a :class:`labcli.core.protocol.Protocol`).

        ``device_info``: the rig's ``DeviceInfo`` (device, firmware, channels);
        ``plan``: the plan table (DataFrame or dict of columns) or None.
        An existing file is overwritten only with ``force=True``.
        """
        path = os.fspath(path)
        if os.path.exists(path) and not force:
            raise StoreError(f"{path} already exists; {exists_hint}.")
        parent = os.path.dirname(os.path.abspath(path))
        if not os.path.isdir(parent):
            raise StoreError(f"cannot create {path}: the directory {parent} does not exist.")
        kind = kind or str(getattr(protocol, "kind", "force"))
        channels = [str(c) for c in (getattr(device_info, "channels", None) or getattr(protocol, "channels", ()))]
        # Built under a temporary name and renamed when whole: a kill during
        # creation leaves no half-made run, and --force keeps the old file until then.
        tmp = path + ".creating"
        try:
            # fs_strategy "none": freed space is never reused (see the module docstring).
            f = h5py.File(tmp, "w", fs_strategy="none")
        except OSError as e:
            raise StoreError(f"cannot create {path}: {e}.") from None
        try:
            cls._initialise(f, protocol=protocol, device_info=device_info, port=port, operator=operator,
                            plan=plan, imported=imported, source=source, started=started, kind=kind,
                            channels=channels)
            f.flush()
            os.fsync(f.id.get_vfd_handle())
        except BaseException:
            f.close()
            os.unlink(tmp)
            raise
        f.close()
        os.replace(tmp, path)
        return cls.open(path, "a")

    @staticmethod
    def _initialise(f: h5py.File, *, protocol: Any, device_info: Any, port: str, operator: str, plan: Any,
                    imported: bool, source: str, started: str | None, kind: str, channels: list[str]) -> None:
        from ... import __version__

        a = f.attrs
        a["NX_class"] = "NXentry"
        a["schema"] = SCHEMA
        a["schema_version"] = SCHEMA_VERSION
        a["labcli_version"] = __version__
        a["kind"] = kind
        a["protocol"] = str(getattr(protocol, "name", ""))
        a["device"] = str(getattr(device_info, "device", "") or "")
        a["firmware"] = str(getattr(device_info, "firmware", "") or "")
        a["port"] = str(port or getattr(device_info, "port", "") or "")
        a["channels"] = channels
        a["operator"] = str(operator or "")
        a["started"] = started or utc_now()
        a["imported"] = bool(imported)
        a["source"] = str(source)
        _text_dataset(f, "protocol", str(getattr(protocol, "text", "")),
                      name=str(getattr(protocol, "name", "")), kind=kind,
                      path=str(getattr(protocol, "path", "") or ""))
        gain, offset, units = _calibration_arrays(protocol, len(channels))
        cal = f.create_group("calibration")
        cal.attrs["NX_class"] = "NXcollection"
        cal.attrs["channels"] = channels
        _dataset(cal, "gain", gain, ",".join(f"{u}/count" if u else "1/count" for u in units))
        _dataset(cal, "offset", offset, ",".join(units))
        if plan is not None:
            cols = plan.to_dict("list") if hasattr(plan, "to_dict") else dict(plan)
            g = f.create_group("plan")
            g.attrs["NX_class"] = "NXcollection"
            _write_columns(g, cols, list(cols))
        # Every group the run will need exists from the start: the root's link
        # list is never changed again, so no later crash can damage it.
        for name in (record_type(kind).collection, "split", "models"):
            f.create_group(name).attrs["NX_class"] = "NXcollection"
        dcpl = h5py.h5p.create(h5py.h5p.DATASET_CREATE)
        dcpl.set_alloc_time(h5py.h5d.ALLOC_TIME_EARLY)
        index = f.create_dataset("index", shape=(INDEX_SLOTS,), dtype=h5py.ref_dtype, dcpl=dcpl)
        index.attrs["units"] = ""

    @classmethod
    def open(cls, path: str | os.PathLike, mode: str = "r") -> "RunFile":
        """Open an existing run file for reading (``"r"``) or resuming (``"a"``)."""
        path = os.fspath(path)
        if mode not in ("r", "a"):
            raise ValueError(f"mode must be 'r' or 'a', got {mode!r}")
        if not os.path.exists(path):
            raise StoreError(f"{path} does not exist; check the path.")
        if os.path.isdir(path):
            raise StoreError(f"{path} is a directory, not a run file.")
        if not os.access(path, os.R_OK) or (mode == "a" and not os.access(path, os.W_OK)):
            raise StoreError(f"{path} cannot be {'read' if mode == 'r' else 'written'}: permission denied.")
        try:
            is_hdf5 = h5py.is_hdf5(path)
        except OSError:
            is_hdf5 = False
        if not is_hdf5:
            raise StoreError(
                f"{path} is not an HDF5 file; run files are written by 'labcli acquire' or 'labcli import'."
            )
        try:
            f = cls._h5open(path, mode)
        except OSError as e:
            if "unable to lock file" in str(e).lower():
                if mode == "r":
                    # A read lock is refused only while a writer holds the file.
                    raise StoreError(
                        f"{path} is open for writing in another process; wait for that run to end and try again."
                    ) from None
                # A write lock is refused while anyone holds the file, a reader included.
                raise StoreError(
                    f"{path} is open in another program (a viewer, or a run still recording); "
                    "close it there and try again."
                ) from None
            raise StoreError(f"{path} is damaged or truncated and HDF5 cannot open it; use a backup copy.") from None
        try:
            schema = f.attrs.get("schema")
            version = f.attrs.get("schema_version")
        except (OSError, KeyError, RuntimeError):
            f.close()
            raise StoreError(f"{path} is damaged or truncated and HDF5 cannot open it; use a backup copy.") from None
        if schema is None or _str(schema) != SCHEMA:
            f.close()
            found = "no schema attribute" if schema is None else f"schema {_str(schema)!r}"
            raise StoreError(f"{path} is an HDF5 file but not a labcli run file ({found}, expected '{SCHEMA}').")
        try:
            version = int(version)
        except (TypeError, ValueError):
            f.close()
            raise StoreError(f"{path} has no valid schema_version attribute; the file is damaged.") from None
        if version > SCHEMA_VERSION:
            f.close()
            raise StoreError(
                f"{path} uses run-file schema version {version}, newer than this labcli reads "
                f"({SCHEMA_VERSION}); upgrade labcli."
            )
        try:
            return cls(f, path)
        except (OSError, KeyError, RuntimeError):
            f.close()
            raise StoreError(f"{path} is damaged or truncated and HDF5 cannot read it; use a backup copy.") from None

    @staticmethod
    def _h5open(path: str, mode: str) -> h5py.File:
        try:
            return h5py.File(path, mode)
        except OSError as e:
            msg = str(e).lower()
            # errno 11: another process holds the lock.  Any other lock failure
            # means a file system without locks (some network mounts), where
            # HDF5 advises opening without them.
            if "unable to lock file" in msg and "errno = 11" not in msg:
                return h5py.File(path, mode, locking=False)
            raise

    def close(self) -> None:
        if self._f.id.valid:
            if self._f.mode != "r":
                self._commit()
            self._f.close()

    def __enter__(self) -> "RunFile":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def _commit(self) -> None:
        """Push everything written so far to the disk (flush, then fsync)."""
        self._f.flush()
        os.fsync(self._f.id.get_vfd_handle())

    # ----------------------------------------------------------- metadata

    @property
    def attrs(self) -> dict[str, Any]:
        """The run's root attributes as plain Python values."""
        return {k: _plain(v) for k, v in self._f.attrs.items()}

    @property
    def kind(self) -> str:
        return _str(self._f.attrs.get("kind", "force"))

    @property
    def channels(self) -> tuple[str, ...]:
        return self._channels

    @property
    def protocol_text(self) -> str:
        """The protocol TOML embedded verbatim when the run was created."""
        if "protocol" not in self._f:
            return ""
        return _str(self._f["protocol"][()])

    def calibration(self) -> dict[str, Any]:
        """Per-channel gain (SI/count), offset (SI) and units as stored."""
        g = self._f["calibration"]
        units = _str(g["offset"].attrs["units"]).split(",")
        return {"channels": self.channels, "gain": g["gain"][()], "offset": g["offset"][()], "units": tuple(units)}

    def plan_table(self):
        """The plan table stored at creation (DataFrame), or None."""
        import pandas as pd

        if "plan" not in self._f:
            return None
        return pd.DataFrame(_read_columns(self._f["plan"]))

    @property
    def _records_name(self) -> str:
        return record_type(self.kind).collection

    # ----------------------------------------------------------- writing

    def _check_writable(self) -> None:
        if self._f.mode == "r":
            raise StoreError(f"{self.path} is open read-only; open it with mode 'a' to add records.")

    def _new_group(self, collection: str, rid: int, label: str) -> h5py.Group:
        if (collection, rid) in self._index:
            raise StoreError(f"{label} is already complete in {self.path}; a stored record is never overwritten.")
        # The scan at opening read every link list; nothing but this object changes them since.
        if collection in self._unreadable:
            raise StoreError(
                f"the list of {collection} in {self.path} is damaged, so no record can be added; its complete "
                "records can still be read: copy them to a new file with 'labcli export' and 'labcli import'."
            )
        if collection not in self._f:
            self._f.create_group(collection).attrs["NX_class"] = "NXcollection"
        parent = self._f[collection]
        base = f"{rid:06d}"
        # Leftovers of interrupted writes stay where they are, ignored, and the
        # new attempt takes the next free name (000012, 000012.1, ...).  Removing
        # them frees blocks at the end of the file; HDF5 then shrinks the file at
        # the next flush, and a kill at that moment left a file that no longer
        # opens ("truncated file"), as the kill tests showed.
        name = base
        n = 0
        while name in parent:
            n += 1
            name = f"{base}.{n}"
        g = parent.create_group(name)
        g.attrs["NX_class"] = "NXcollection"
        g.attrs["complete"] = False  # first attribute; set True in place once all else is on disk
        return g

    @functools.cached_property
    def _values_units(self) -> str:
        """The units of a window's calibrated values, one per channel (read once, on the first write)."""
        return _str(self._f["calibration/offset"].attrs["units"])

    @functools.cached_property
    def _index_dataset(self) -> h5py.Dataset | None:
        return self._f.get("index")

    def _write_common(self, g: h5py.Group, record: Mapping, attrs: Mapping[str, Any],
                      windows: list[Window]) -> None:
        g.attrs["order"] = self._order
        g.attrs["started"] = str(record.get("started", "") or "")
        g.attrs["ended"] = str(record.get("ended", "") or utc_now())
        for key, v in attrs.items():
            g.attrs[key] = v
        extra = record.get("extra") or {}
        if extra:
            e = g.create_group("extra")
            e.attrs["NX_class"] = "NXcollection"
            e.attrs["columns"] = list(extra)
            for name, v in extra.items():
                if isinstance(v, str):
                    _text_dataset(e, name, v)
                elif isinstance(v, (int, np.integer)) and not isinstance(v, bool):
                    _dataset(e, name, np.int64(v), _column_units(name))
                else:
                    _dataset(e, name, math.nan if v is None else float(v), _column_units(name))
        for name, arrays, settle in windows:
            w = g.create_group(name)
            w.attrs["NX_class"] = "NXlog"
            w.attrs["channels"] = list(self.channels)
            _dataset(w, "time", arrays["time"], "s", raw=True)
            _dataset(w, "counts", arrays["counts"], "counts", raw=True)
            _dataset(w, "values", arrays["values"], self._values_units, raw=True)
            _dataset(w, "seq", arrays["seq"], "1", raw=True)
            for sk, sv in settle.items():
                w.attrs[sk] = sv

    def _finish(self, g: h5py.Group, collection: str, rid: int) -> None:
        index = self._index_dataset
        if index is not None and self._order < index.shape[0]:
            # A write in place into storage allocated at creation: no HDF5
            # structure changes, so the record stays reachable even if a later
            # crash damages the group's list of links.
            index[self._order] = g.ref
        if self.sync_each_record:
            self._commit()
        g.attrs.modify("complete", True)
        if self.sync_each_record:
            self._commit()
        self._index[(collection, rid)] = (self._order, g.ref)
        self._incomplete.discard((collection, rid))
        self._order += 1

    def _record_id(self, record: Mapping, what: str) -> tuple[int, str]:
        """The id of a ``what`` ("trial", "push", "point") record and its label for messages."""
        self._check_writable()
        if what not in record:
            raise StoreError(f"{what} record lacks '{what}' (the {what} id).")
        rid = int(record[what])
        label = f"{what} {rid}"
        if not 0 <= rid <= MAX_ID:
            raise StoreError(f"{label}: {what} ids must be between 0 and {MAX_ID}.")
        return rid, label

    def write(self, record: Mapping) -> None:
        """Write one record of the run's kind whole; it counts only once it is on disk."""
        writer = {"trials": self.write_trial, "pushes": self.write_push, "points": self.write_point}
        writer[self._records_name](record)

    def write_trial(self, record: TrialRecord | Mapping) -> None:
        """Write one force/angle trial whole; it counts only once it is on disk.

        ``record``: see :class:`TrialRecord`.  Raises StoreError if the trial is
        already complete in the file or the record is malformed (nothing is written then).
        """
        tid, label = self._record_id(record, "trial")
        p0 = _vector(record, "P0_MPa", 4, "baseline pressures P_L1,P_R1,P_L2,P_R2 in MPa", label)
        p = _vector(record, "P_MPa", 4, "loaded pressures P_L1,P_R1,P_L2,P_R2 in MPa", label)
        theta = _vector(record, "theta_rad", 2, "joint deflections in rad", label)
        force = _vector(record, "force_N", 2, "Fx, Fy in N", label)
        pot0 = _vector(record, "pot0_rad", 2, "baseline potentiometer angles in rad", label) if "pot0_rad" in record else None
        mass = _scalar(record, "mass_kg", label)
        direction = _scalar(record, "direction_rad", label)
        common = _checked_common(record, len(self.channels), label)
        g = self._new_group("trials", tid, label)
        g.attrs["trial"] = tid
        plan = dict(record.get("plan") or {})
        if "set" in record and "set" not in plan:
            plan["set"] = record["set"]
        for key, v in plan.items():
            g.attrs[f"plan_{key}"] = v if isinstance(v, str) else float(v)
        pressure_attrs = {"channels": ",".join(PRESSURE_NAMES)}
        _dataset(g, "P0", p0, "MPa", **pressure_attrs)
        _dataset(g, "P", p, "MPa", **pressure_attrs)
        _dataset(g, "theta", theta, "rad")
        if pot0 is not None:
            _dataset(g, "pot0", pot0, "rad")
        _dataset(g, "F", force, "N", components="Fx,Fy")
        _dataset(g, "mass", mass, "kg")
        _dataset(g, "direction", direction, "rad")
        self._write_common(g, record, *common)
        self._finish(g, "trials", tid)

    def write_push(self, record: PushRecord | Mapping) -> None:
        """Write one object push whole (see :class:`PushRecord`); crash-safe as :meth:`write_trial`."""
        pid, label = self._record_id(record, "push")
        p0 = _vector(record, "P0_MPa", 4, "baseline pressures P_L1,P_R1,P_L2,P_R2 in MPa", label)
        p = _vector(record, "P_MPa", 4, "pressures with the object pushed in, MPa", label)
        if "object" not in record:
            raise StoreError(f"{label} record lacks 'object' (the object name).")
        radius = _scalar(record, "R_m", label)
        distance = _scalar(record, "d_m", label)
        phi = _scalar(record, "phi_rad", label)
        stiffness = _scalar(record, "true_stiffness_N_per_m", label)
        theta = _vector(record, "theta_rad", 2, "joint deflections in rad", label) if "theta_rad" in record else None
        pot0 = _vector(record, "pot0_rad", 2, "baseline potentiometer angles in rad", label) if "pot0_rad" in record else None
        common = _checked_common(record, len(self.channels), label)
        g = self._new_group("pushes", pid, label)
        g.attrs["push"] = pid
        g.attrs["object"] = str(record["object"])
        g.attrs["category"] = str(record.get("category", "") or "")
        pressure_attrs = {"channels": ",".join(PRESSURE_NAMES)}
        _dataset(g, "P0", p0, "MPa", **pressure_attrs)
        _dataset(g, "P", p, "MPa", **pressure_attrs)
        _dataset(g, "R", radius, "m")
        _dataset(g, "d", distance, "m")
        _dataset(g, "phi", phi, "rad")
        _dataset(g, "true_stiffness", stiffness, "N/m")
        if theta is not None:
            _dataset(g, "theta", theta, "rad")
        if pot0 is not None:
            _dataset(g, "pot0", pot0, "rad")
        self._write_common(g, record, *common)
        self._finish(g, "pushes", pid)

    # ----------------------------------------------------------- reading records

    @staticmethod
    def _identify(g: h5py.Group) -> tuple[str, int, bool, int]:
        """(collection, id, complete, order) of a record group; raises if it cannot be read."""
        a = g.attrs
        if "trial" in a:
            collection, rid = "trials", int(a["trial"])
        elif "push" in a:
            collection, rid = "pushes", int(a["push"])
        elif "point" in a:
            collection, rid = "points", int(a["point"])
        else:
            raise KeyError("no id")
        ok = bool(a.get("complete", False))
        return collection, rid, ok, int(a["order"]) if ok else -1

    def _scan(self) -> tuple[list[tuple[str, int, int, Any]], set[tuple[str, int]]]:
        """Complete records as (collection, order, id, reference), and (collection, id) only incomplete.

        Records are found by name under /trials and /pushes and, independently,
        through /index (object references written in place), so that damage to
        a group's link list after a crash loses no complete record.
        """
        complete: dict[tuple[str, int], tuple[int, Any]] = {}
        incomplete: set[tuple[str, int]] = set()

        def visit(get_group, fallback: tuple[str, int] | None = None) -> None:
            try:
                g = get_group()
                collection, rid, ok, order = self._identify(g)
            except Exception:  # a crash's leftovers may be unreadable in any way: never complete
                if fallback is not None:
                    incomplete.add(fallback)
                return
            if ok:
                complete.setdefault((collection, rid), (order, g.ref))
            else:
                incomplete.add((collection, rid))

        for collection in ("trials", "pushes", "points"):
            try:
                parent = self._f[collection] if collection in self._f else None
                keys = list(parent) if parent is not None else []
            except Exception:
                self._unreadable.add(collection)
                keys = []
            for key in keys:
                try:
                    fallback = (collection, int(key.split(".")[0]))
                except ValueError:
                    continue
                visit(lambda parent=parent, key=key: parent[key], fallback)
        try:
            refs = self._f["index"][()] if "index" in self._f else []
        except Exception:
            refs = []
        for ref in refs:
            if not ref:
                break  # slots are filled in recording order
            visit(lambda ref=ref: self._f[ref])
        rows = sorted(((c, order, rid, ref) for (c, rid), (order, ref) in complete.items()), key=lambda r: r[:3])
        return rows, incomplete - set(complete)

    def _complete(self, collection: str | None = None) -> list[tuple[int, int, Any]]:
        """(order, id, object reference) of the complete records, in recording order."""
        c = collection or self._records_name
        return sorted(((order, rid, ref) for (cc, rid), (order, ref) in self._index.items() if cc == c),
                      key=lambda row: row[:2])

    def completed_ids(self, collection: str | None = None) -> list[int]:
        """Ids of the complete trials (pushes for a push run), in recording order."""
        return [rid for _, rid, _ in self._complete(collection)]

    def incomplete_ids(self, collection: str | None = None) -> list[int]:
        """Ids with only groups left incomplete by an interrupted write (never counted)."""
        c = collection or self._records_name
        return sorted(rid for cc, rid in self._incomplete if cc == c)

    def first_incomplete(self, plan_ids: Iterable[int]) -> int | None:
        """The first id of ``plan_ids`` not yet complete in the file (None: all done)."""
        done = set(self.completed_ids())
        for i in plan_ids:
            if int(i) not in done:
                return int(i)
        return None

    def _complete_groups(self, collection: str) -> tuple[list[int], list[h5py.Group]]:
        complete = self._complete(collection)
        return [rid for _, rid, _ in complete], [self._f[ref] for _, _, ref in complete]

    def _complete_group(self, collection: str, rid: int) -> h5py.Group:
        entry = self._index.get((collection, rid))
        if entry is None:
            what = {"trials": "trial", "pushes": "push", "points": "point"}.get(collection, collection)
            raise StoreError(f"{what} {rid} is not a complete record in {self.path}.")
        return self._f[entry[1]]

    @staticmethod
    def _read_windows(g: h5py.Group) -> tuple[dict, dict]:
        raw, settle = {}, {}
        for name, key in (("baseline", "baseline"), ("loaded", "load")):
            if name not in g:
                continue
            w = g[name]
            raw[key] = {"t_s": w["time"][()], "counts": w["counts"][()], "si": w["values"][()], "seq": w["seq"][()]}
            s = {k: _plain(v) for k, v in w.attrs.items() if k not in ("NX_class", "channels")}
            if s:
                settle[key] = s
        return raw, settle

    @staticmethod
    def _read_extra(g: h5py.Group) -> dict:
        if "extra" not in g:
            return {}
        e = g["extra"]
        out = {}
        for name in [_str(c) for c in e.attrs.get("columns", list(e))]:
            v = e[name][()]
            out[name] = _str(v) if isinstance(v, (bytes, str)) else v.item()
        return out

    def read_trial(self, trial: int) -> dict:
        """One complete trial back as a :class:`TrialRecord`-shaped dict (windows as stored)."""
        g = self._complete_group("trials", int(trial))
        raw, settle = self._read_windows(g)
        rec: dict[str, Any] = {
            "trial": int(g.attrs["trial"]),
            "P0_MPa": g["P0"][()], "P_MPa": g["P"][()], "theta_rad": g["theta"][()], "force_N": g["F"][()],
            "mass_kg": float(g["mass"][()]), "direction_rad": float(g["direction"][()]),
            "started": _str(g.attrs["started"]), "ended": _str(g.attrs["ended"]),
            "accepted": _str(g.attrs["accepted"]), "order": int(g.attrs["order"]),
            "plan": {k[5:]: _plain(v) for k, v in g.attrs.items() if k.startswith("plan_")},
            "raw": raw, "settle": settle, "extra": self._read_extra(g),
        }
        if "pot0" in g:
            rec["pot0_rad"] = g["pot0"][()]
        return rec

    def read_push(self, push: int) -> dict:
        """One complete push back as a :class:`PushRecord`-shaped dict."""
        g = self._complete_group("pushes", int(push))
        raw, settle = self._read_windows(g)
        optional = {key: g[name][()] for key, name in (("theta_rad", "theta"), ("pot0_rad", "pot0")) if name in g}
        return {
            **optional,
            "push": int(g.attrs["push"]), "object": _str(g.attrs["object"]), "category": _str(g.attrs["category"]),
            "R_m": float(g["R"][()]), "d_m": float(g["d"][()]), "phi_rad": float(g["phi"][()]),
            "true_stiffness_N_per_m": float(g["true_stiffness"][()]),
            "P0_MPa": g["P0"][()], "P_MPa": g["P"][()],
            "started": _str(g.attrs["started"]), "ended": _str(g.attrs["ended"]),
            "accepted": _str(g.attrs["accepted"]), "order": int(g.attrs["order"]),
            "raw": raw, "settle": settle, "extra": self._read_extra(g),
        }

    # ----------------------------------------------------------- tables

    def trial_table(self):
        """The trial table (table-formats.md): MPa, N, degrees and grams; ``set`` from the split."""
        import pandas as pd

        ids, groups = self._complete_groups("trials")
        sets = self.set_of()
        cols: dict[str, Any] = {c: [] for c in TRIAL_COLUMNS}
        mass, direction = [], []
        for t, g in zip(ids, groups):
            p0, p, theta, force = g["P0"][()], g["P"][()], g["theta"][()], g["F"][()]
            cols["trial"].append(t)
            cols["set"].append(sets.get(t, ""))
            for name, v in zip(BASELINE_COLUMNS, p0):
                cols[name].append(float(v))
            for name, v in zip(PRESSURE_NAMES, p):
                cols[name].append(float(v))
            cols["theta1_deg"].append(math.degrees(theta[0]))
            cols["theta2_deg"].append(math.degrees(theta[1]))
            cols["Fx_N"].append(float(force[0]))
            cols["Fy_N"].append(float(force[1]))
            mass.append(float(g["mass"][()]) * 1e3)
            direction.append(math.degrees(float(g["direction"][()])))
        df = pd.DataFrame(cols)
        df["trial"] = df["trial"].astype("int64")
        df["set"] = df["set"].astype(object)
        for c in ("theta1_deg", "theta2_deg"):
            df[c] = to_edge(df[c].to_numpy())
        if np.any(np.isfinite(mass)):
            df["mass_g"] = to_edge(mass)
        if np.any(np.isfinite(direction)):
            df["direction_deg"] = to_edge(direction)
        self._add_extras(df, groups)
        return df

    def push_table(self):
        """The push table (table-formats.md): m, degrees, MPa; ``phi_deg`` NaN when unknown."""
        import pandas as pd

        ids, groups = self._complete_groups("pushes")
        cols: dict[str, Any] = {c: [] for c in PUSH_COLUMNS}
        stiffness = []
        for t, g in zip(ids, groups):
            cols["push"].append(t)
            cols["object"].append(_str(g.attrs["object"]))
            cols["R_m"].append(float(g["R"][()]))
            cols["d_m"].append(float(g["d"][()]))
            cols["phi_deg"].append(math.degrees(float(g["phi"][()])))
            for name, v in zip(BASELINE_COLUMNS, g["P0"][()]):
                cols[name].append(float(v))
            for name, v in zip(PRESSURE_NAMES, g["P"][()]):
                cols[name].append(float(v))
            cols["category"].append(_str(g.attrs["category"]))
            stiffness.append(float(g["true_stiffness"][()]))
        df = pd.DataFrame(cols)
        df["push"] = df["push"].astype("int64")
        df["phi_deg"] = to_edge(df["phi_deg"].to_numpy())
        if np.any(np.isfinite(stiffness)):
            df["true_stiffness_N_per_m"] = stiffness
        self._add_extras(df, groups)
        return df

    def _add_extras(self, df: Any, groups: list[h5py.Group]) -> None:
        """Append the imported columns labcli does not know, in first-seen order; NaN where a record lacks one."""
        extras = [self._read_extra(g) for g in groups]
        for name in dict.fromkeys(name for e in extras for name in e):
            df[name] = [e.get(name, math.nan) for e in extras]

    # ----------------------------------------------------------- rPAM points

    def write_point(self, record: Mapping) -> None:
        """Write one rPAM point whole (stretch test or joint map); crash-safe as :meth:`write_trial`.

        ``record``: ``point`` (id), ``experiment`` ("stretch" | "joint", as the run's kind
        says), ``P_MPa`` (2,) P_A, P_B; stretch points ``mass_kg``, ``L_m`` (actuator A's
        length) and ``lambda`` (L / L0); joint-map points ``alpha_rad`` (deflection from the
        vented baseline) and optionally ``P0_MPa`` (2,) and ``pot0_rad`` of the baseline and
        ``L_m``; ``plan`` (the set values as typed: ``mass_g``, ``P_A_kPa``, ``P_B_kPa``),
        ``settle``, ``raw``, ``started``, ``ended`` as in :class:`TrialRecord`.
        """
        pid, label = self._record_id(record, "point")
        experiment = _RPAM_EXPERIMENTS.get(self.kind)
        if experiment is None:
            raise StoreError(f"{self.path} is a {self.kind} run; rPAM points go into runs of kind "
                             "rpam-stretch or rpam-joint.")
        if record.get("experiment", experiment) != experiment:
            raise StoreError(f"{label}: a {record['experiment']} point cannot go into {self.path}, "
                             f"a {self.kind} run.")
        p = _vector(record, "P_MPa", 2, "pressures P_A, P_B in MPa", label)
        p0 = _vector(record, "P0_MPa", 2, "baseline pressures P_A, P_B in MPa", label) if "P0_MPa" in record else None
        needed = ("mass_kg", "L_m", "lambda") if experiment == "stretch" else ("alpha_rad",)
        values = {}
        for key in needed:
            values[key] = _scalar(record, key, label)
            if not math.isfinite(values[key]):
                raise StoreError(f"{label} record lacks a finite '{key}', which a {experiment} point needs.")
        for key in ("L_m", "pot0_rad"):
            if key not in values and key in record:
                values[key] = _scalar(record, key, label)
        common = _checked_common(record, len(self.channels), label)
        g = self._new_group("points", pid, label)
        g.attrs["point"] = pid
        g.attrs["experiment"] = experiment
        for key, v in (record.get("plan") or {}).items():
            g.attrs[f"plan_{key}"] = v if isinstance(v, str) else float(v)
        _dataset(g, "P", p, "MPa", channels="P_A,P_B")
        if p0 is not None:
            _dataset(g, "P0", p0, "MPa", channels="P_A,P_B")
        names = {"mass_kg": ("mass", "kg"), "L_m": ("L", "m"), "lambda": ("lambda", "1"),
                 "alpha_rad": ("alpha", "rad"), "pot0_rad": ("pot0", "rad")}
        for key, v in values.items():
            _dataset(g, names[key][0], v, names[key][1])
        self._write_common(g, record, *common)
        self._finish(g, "points", pid)

    def point_table(self):
        """The table of an rPAM run (DataFrame): MPa and m, grams and degrees at the edge.

        Stretch test: ``point, mass_g, P_A, P_B, L_m, lambda``; joint map: ``point, P_A,
        P_B, alpha_deg, P_A0, P_B0, L_m`` (pressures in MPa, ``alpha_deg`` the deflection
        from the vented baseline); then the set values as ``set_mass_g``, ``set_P_A_kPa``,
        ``set_P_B_kPa``; then the columns of an imported table labcli does not know.  Rows in
        recording order.  ``labcli export`` writes this table and ``labcli import`` reads it back.
        """
        import pandas as pd

        experiment = _RPAM_EXPERIMENTS.get(self.kind)
        if experiment is None:
            raise StoreError(f"{self.path} is a {self.kind} run, not an rPAM stretch-test or joint-map run.")
        ids, groups = self._complete_groups("points")
        cols: dict[str, list] = {"point": list(ids)}

        def add(name: str, values: list) -> None:
            cols[name] = values

        def get(g: h5py.Group, key: str, i: int | None = None) -> float:
            if key not in g:
                return math.nan
            v = g[key][()]
            return float(v if i is None else v[i])

        if experiment == "stretch":
            add("mass_g", list(to_edge([get(g, "mass") * 1e3 for g in groups])))
        add("P_A", [get(g, "P", 0) for g in groups])
        add("P_B", [get(g, "P", 1) for g in groups])
        if experiment == "stretch":
            add("L_m", [get(g, "L") for g in groups])
            add("lambda", [get(g, "lambda") for g in groups])
        else:
            add("alpha_deg", list(to_edge([math.degrees(get(g, "alpha")) for g in groups])))
            add("P_A0", [get(g, "P0", 0) for g in groups])
            add("P_B0", [get(g, "P0", 1) for g in groups])
            add("L_m", [get(g, "L") for g in groups])
        for key in ("mass_g", "P_A_kPa", "P_B_kPa"):
            vals = [float(g.attrs.get(f"plan_{key}", math.nan)) for g in groups]
            if any(math.isfinite(v) for v in vals):
                add(f"set_{key}", vals)
        df = pd.DataFrame(cols)
        df["point"] = df["point"].astype("int64")
        self._add_extras(df, groups)
        return df

    # ----------------------------------------------------------- split and models

    def set_split(self, fit_ids: Iterable[int], validation_ids: Iterable[int], strategy: str = "manual",
                  seed: int | None = None) -> None:
        """Store which complete trials fit and which validate (replaces an earlier split)."""
        self._check_writable()
        fit = [int(i) for i in fit_ids]
        val = [int(i) for i in validation_ids]
        both = sorted(set(fit) & set(val))
        if both:
            raise StoreError(f"trial {both[0]} cannot be in both the fit and the validation set.")
        if len(set(fit)) != len(fit) or len(set(val)) != len(val):
            raise StoreError("a trial id appears twice in the split.")
        done = set(self.completed_ids("trials"))
        missing = [i for i in fit + val if i not in done]
        if missing:
            raise StoreError(f"trial {missing[0]} is not a complete trial in {self.path}, so it cannot join the split.")
        if "split" not in self._f:
            self._f.create_group("split").attrs["NX_class"] = "NXcollection"
        g = self._f["split"]
        g.attrs["strategy"] = str(strategy)
        g.attrs["seed"] = -1 if seed is None else int(seed)
        g.attrs["created"] = utc_now()
        for name, ids in (("fit", fit), ("validation", val)):
            data = np.asarray(ids, dtype=np.int64)
            if name in g and g[name].shape == data.shape:
                g[name][...] = data  # in place: nothing freed (see the module docstring)
                continue
            if name in g:
                del g[name]
            _dataset(g, name, data, "1")
        self._commit()

    def split_sizes(self) -> tuple[int, int]:
        """The fit and validation counts of the run's embedded protocol (its settings' ``default_split``)."""
        from ..protocol import loads_protocol

        try:
            settings = loads_protocol(self.protocol_text, source=f"{self.path} (embedded protocol)").settings
        except ConfigError:
            settings = None
        sizes = getattr(settings, "default_split", None)
        if sizes is None:
            raise ConfigError(f"{self.path}: the run's protocol gives no fit and validation counts; "
                              "give --fit and --validation.")
        return int(sizes[0]), int(sizes[1])

    def assign_split(self, n_fit: int | None, n_validation: int | None, strategy: str = "sequential",
                     seed: int | None = None) -> dict[str, Any]:
        """Choose (see :func:`choose_split`) and store a split; returns :meth:`split`.

        A count left None comes from the run's protocol (:meth:`split_sizes`).
        """
        if n_fit is None or n_validation is None:
            default_fit, default_validation = self.split_sizes()
            n_fit = default_fit if n_fit is None else n_fit
            n_validation = default_validation if n_validation is None else n_validation
        try:
            fit, val = choose_split(self.completed_ids("trials"), n_fit, n_validation, strategy, seed)
        except ConfigError as e:
            raise ConfigError(f"{self.path}: {e}") from None
        self.set_split(fit, val, strategy, (0 if seed is None else seed) if strategy == "random" else None)
        return self.split()

    def split(self) -> dict[str, Any] | None:
        """``{"fit": [...], "validation": [...], "strategy", "seed" (None), "created"}`` or None."""
        if "split" not in self._f or "fit" not in self._f["split"]:
            return None
        g = self._f["split"]
        seed = int(g.attrs.get("seed", -1))
        return {
            "fit": [int(i) for i in g["fit"][()]],
            "validation": [int(i) for i in g["validation"][()]],
            "strategy": _str(g.attrs.get("strategy", "")),
            "seed": None if seed < 0 else seed,
            "created": _str(g.attrs.get("created", "")),
        }

    def set_of(self) -> dict[int, str]:
        """Trial id -> "fit" / "validation" from the stored split (unassigned ids absent)."""
        s = self.split()
        if s is None:
            return {}
        out = {i: "fit" for i in s["fit"]}
        out.update({i: "validation" for i in s["validation"]})
        return out

    def record_model(self, name: str, json_text: str) -> None:
        """Store a fitted model's parameters (JSON text) under ``/models/<name>``, replacing one of that name."""
        self._check_writable()
        if not name or "/" in name or name.startswith("."):
            raise StoreError(f"model name {name!r} must be non-empty and contain no '/'.")
        if "models" not in self._f:
            self._f.create_group("models").attrs["NX_class"] = "NXcollection"
        g = self._f["models"]
        if name in g:
            del g[name]
        _text_dataset(g, name, str(json_text), created=utc_now())
        self._commit()

    def models(self) -> dict[str, str]:
        """Model name -> JSON text, as recorded."""
        if "models" not in self._f:
            return {}
        return {name: _str(ds[()]) for name, ds in self._f["models"].items()}

    # ----------------------------------------------------------- summary

    def summary(self) -> dict[str, Any]:
        """What ``labcli inspect`` shows: metadata, completeness, split, drift, settling."""
        a = self.attrs
        collection = self._records_name
        ids, groups = self._complete_groups(collection)
        incomplete = self.incomplete_ids(collection)
        plan = self.plan_table()
        out: dict[str, Any] = {
            "path": self.path,
            "schema_version": a.get("schema_version"),
            "labcli_version": a.get("labcli_version", ""),
            "kind": a.get("kind", ""),
            "protocol": a.get("protocol", ""),
            "device": a.get("device", ""),
            "firmware": a.get("firmware", ""),
            "port": a.get("port", ""),
            "operator": a.get("operator", ""),
            "started": a.get("started", ""),
            "imported": bool(a.get("imported", False)),
            "channels": list(self.channels),
            "records": collection,
            "complete": len(ids),
            "incomplete": len(incomplete),
            "incomplete_ids": incomplete,
            "planned": None if plan is None else int(len(plan)),
            "split": None,
            "baseline_drift": None,
            "settle": None,
            "models": sorted(self._f["models"]) if "models" in self._f else [],
        }
        s = self.split()
        if s is not None:
            out["split"] = {
                "strategy": s["strategy"], "seed": s["seed"], "fit": len(s["fit"]),
                "validation": len(s["validation"]),
                "unassigned": len(set(ids) - set(s["fit"]) - set(s["validation"])) if collection == "trials" else 0,
            }
        if len(groups) >= 2 and collection != "points":
            p0 = np.array([g["P0"][()] for g in groups])
            index = np.arange(len(groups), dtype=np.float64)
            drift = {}
            for c, name in enumerate(PRESSURE_NAMES):
                slope = np.polyfit(index, p0[:, c], 1)[0]
                drift[name] = {
                    "first_MPa": float(p0[0, c]),
                    "last_MPa": float(p0[-1, c]),
                    "slope_kPa_per_trial": float(slope * 1e3),
                    "max_deviation_kPa": float(np.max(np.abs(p0[:, c] - p0[0, c])) * 1e3),
                }
            out["baseline_drift"] = drift
        if collection == "points":
            out["rpam"] = self._rpam_summary(ids, bool(out["imported"]))
        times = np.array([float(g.attrs.get("settle_time_s", math.nan)) for g in groups])
        accepted = [_str(g.attrs.get("accepted", "")) for g in groups]
        finite = times[np.isfinite(times)]
        out["settle"] = {
            "n": int(finite.size),
            "median_s": float(np.median(finite)) if finite.size else None,
            "max_s": float(np.max(finite)) if finite.size else None,
            "timeout_accepted": int(sum(x == "timeout" for x in accepted)),
            "timeout_ids": [i for i, x in zip(ids, accepted) if x == "timeout"],
        }
        return out

    def _rpam_summary(self, ids: list[int], imported: bool) -> dict[str, Any]:
        """The rPAM part of :meth:`summary`: the experiment, its grid's coverage, ranges measured.

        ``planned``/``missing_ids`` come from the protocol embedded in the run (None for an
        imported table, whose grid need not be the protocol's); ranges are [min, max] over
        the complete points (None when there is none): pressures in kPa, payloads in g,
        deflections in degrees.
        """
        experiment = _RPAM_EXPERIMENTS[self.kind]
        table = self.point_table()

        def span(values: Any, scale: float = 1.0) -> list[float] | None:
            v = np.asarray(values, dtype=np.float64) * scale
            v = v[np.isfinite(v)]
            return [float(v.min()), float(v.max())] if v.size else None

        planned = missing = None
        if not imported:
            from ..protocol import loads_protocol
            from ...experiments.rpam2015.session import acquisition_protocol

            try:
                base = loads_protocol(self.protocol_text, source=f"{self.path} (embedded protocol)")
                grid = [p.point for p in acquisition_protocol(base, experiment).settings.points]
            except LabcliError:
                grid = None
            if grid is not None:
                done = set(ids)
                planned, missing = len(grid), [i for i in grid if i not in done]
        out: dict[str, Any] = {
            "experiment": experiment,
            "title": {"stretch": "stretch test", "joint": "joint map"}[experiment],
            "planned": planned,
            "missing_ids": missing,
            "P_A_kPa": span(table["P_A"], 1e3),
            "P_B_kPa": span(table["P_B"], 1e3),
        }
        if experiment == "stretch":
            masses = sorted({float(m) for m in table["mass_g"] if math.isfinite(m)})
            out["payloads_g"] = masses
            out["lambda"] = span(table["lambda"])
        else:
            out["alpha_deg"] = span(table["alpha_deg"])
        return out


# --------------------------------------------------------------------------- import

NUL_PROBLEM = "holds a NUL character, which a run file cannot store; remove it"


def storable_cells(row: Mapping[str, Any]) -> Iterable[tuple[str, str]]:
    """(column, problem) for each cell of a table row that a run file cannot store.

    HDF5 keeps text as NUL-terminated strings: a NUL inside a text cell would cut it
    short (h5py refuses it outright).  Pass this to the table readers' ``check`` to
    have such cells reported by file, row and column.
    """
    for column, value in row.items():
        if isinstance(value, str) and "\x00" in value:
            yield str(column), NUL_PROBLEM


def _nan_if_empty(v: Any) -> float:
    if v is None or (isinstance(v, str) and v.strip() == ""):
        return math.nan
    return float(v)


def _extra_value(v: Any) -> Any:
    if isinstance(v, str):
        return v
    if isinstance(v, (int, np.integer)):
        return v
    return _nan_if_empty(v)


def _check_storable(columns: Sequence[Any], rows: list[dict], id_col: str) -> None:
    """Refuse, before any file is made, a table holding text a run file cannot store."""
    for c in columns:
        if "\x00" in str(c):
            raise ConfigError(f"the column name {str(c)!r} holds a NUL character, which a run file cannot "
                              "store; rename the column.")
    for row in rows:
        for column, problem in storable_cells(row):
            raise ConfigError(f"{id_col} {row[id_col]}, column {column}: {problem}.")


def import_table(df: Any, path: str | os.PathLike, *, protocol: Any, force: bool = False, source: str = "",
                 operator: str = "") -> RunFile:
    """Build a run file without raw windows from a trial, push or point table (DataFrame).

    The protocol's kind decides which: ``push`` -> push table (:data:`PUSH_COLUMNS`),
    ``rpam-stretch`` / ``rpam-joint`` (an rPAM protocol with its experiment chosen,
    :func:`labcli.experiments.rpam2015.session.acquisition_protocol`) -> the point table of
    :meth:`RunFile.point_table`, otherwise trial table.  The ``set`` column of a trial
    table becomes the split (strategy ``imported``); columns labcli does not know are
    kept per record.  The file is built beside ``path`` and moved into place only when
    whole, so a failed import leaves an existing file untouched.  Returns the run, open
    for reading.
    """
    path = os.fspath(path)
    if os.path.exists(path) and not force:
        raise StoreError(f"{path} already exists; use --force to overwrite it.")
    kind = str(getattr(protocol, "kind", "force"))
    push = kind == "push"
    experiment = _RPAM_EXPERIMENTS.get(kind)
    if experiment is not None:
        from ..tables import POINT_SPECS

        known = set(POINT_SPECS[experiment].names)
        id_col = "point"
    elif push:
        known = set(PUSH_COLUMNS + PUSH_OPTIONAL_COLUMNS)
        id_col = "push"
    else:
        known = set(TRIAL_COLUMNS + TRIAL_OPTIONAL_COLUMNS)
        id_col = "trial"
    rows = df.to_dict("records")
    extras = [c for c in df.columns if c not in known]
    seen: set[int] = set()
    for row in rows:
        rid = int(row[id_col])
        if rid in seen:
            raise ConfigError(f"{id_col} {rid} appears twice in the table; ids must be unique.")
        seen.add(rid)
    _check_storable(list(df.columns), rows, id_col)
    fit, val = [], []
    if not push and experiment is None:
        for row in rows:
            s = "" if _missing(row.get("set")) else str(row["set"])
            if s not in ("fit", "validation", ""):
                raise ConfigError(f"trial {int(row['trial'])}: set must be fit, validation or empty, got {s!r}.")
            (fit if s == "fit" else val if s == "validation" else []).append(int(row["trial"]))
    tmp = path + ".importing"
    run = RunFile.create(tmp, protocol=protocol, force=True, imported=True, source=source, operator=operator)
    run.sync_each_record = False  # the file only becomes the run once whole (os.replace below)
    try:
        for row in rows:
            extra = {c: _extra_value(row[c]) for c in extras}
            if experiment is not None:
                run.write_point(_point_record(row, experiment, protocol, extra))
                continue
            common = {"P0_MPa": [row[c] for c in BASELINE_COLUMNS], "P_MPa": [row[c] for c in PRESSURE_NAMES],
                      "accepted": "imported", "ended": "", "extra": extra}
            if push:
                run.write_push({
                    "push": int(row["push"]), "object": str(row["object"]),
                    "R_m": float(row["R_m"]), "d_m": float(row["d_m"]),
                    "phi_rad": math.radians(_nan_if_empty(row.get("phi_deg"))),
                    "category": "" if _missing(row.get("category")) else str(row["category"]),
                    "true_stiffness_N_per_m": _nan_if_empty(row.get("true_stiffness_N_per_m")),
                    **common,
                })
            else:
                run.write_trial({
                    "trial": int(row["trial"]),
                    "theta_rad": [math.radians(row["theta1_deg"]), math.radians(row["theta2_deg"])],
                    "force_N": [row["Fx_N"], row["Fy_N"]],
                    "mass_kg": _nan_if_empty(row.get("mass_g")) * 1e-3,
                    "direction_rad": math.radians(_nan_if_empty(row.get("direction_deg"))),
                    **common,
                })
        if fit or val:
            run.set_split(fit, val, "imported")
        run.close()
        os.replace(tmp, path)
    except BaseException:
        run.close()
        os.unlink(tmp)
        raise
    return RunFile.open(path)


def _point_record(row: Mapping[str, Any], experiment: str, protocol: Any, extra: dict) -> dict[str, Any]:
    """One row of an rPAM point table as the record :meth:`RunFile.write_point` takes (SI)."""

    def value(key: str) -> float:
        return _nan_if_empty(row.get(key))

    record: dict[str, Any] = {
        "point": int(row["point"]), "experiment": experiment, "P_MPa": [value("P_A"), value("P_B")],
        "accepted": "imported", "ended": "", "extra": extra,
    }
    plan = {key: value(f"set_{key}") for key in (("mass_g",) if experiment == "stretch" else ()) + ("P_A_kPa", "P_B_kPa")}
    record["plan"] = {k: v for k, v in plan.items() if math.isfinite(v)}
    length = value("L_m")
    if experiment == "stretch":
        record["mass_kg"] = value("mass_g") * 1e-3
        record["L_m"] = length
        stretch = value("lambda")
        if not math.isfinite(stretch):
            # A table without lambda: the stretch of actuator A over its protocol's rest length.
            stretch = length / float(protocol.settings.L0_m)
        record["lambda"] = stretch
    else:
        record["alpha_rad"] = math.radians(value("alpha_deg"))
        p0 = [value("P_A0"), value("P_B0")]
        if all(math.isfinite(v) for v in p0):
            record["P0_MPa"] = p0
        if math.isfinite(length):
            record["L_m"] = length
    return record


def _missing(v: Any) -> bool:
    return v is None or (isinstance(v, float) and math.isnan(v)) or (isinstance(v, str) and v == "")
