"""Schema 2 of the run file: flags kept per record, the session log, version-1 files read as 0.1 read them."""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import warnings
from pathlib import Path
from types import SimpleNamespace

import h5py
import pytest
from support.records import CHANNELS, FakeDevice, FakeProtocol, assert_record_stored, make_record

from labcli.core.store import SCHEMA_VERSION, RunFile
from labcli.errors import LabcliWarning, StoreError

ROOT = Path(__file__).resolve().parents[2]
V1 = ROOT / "tests" / "data" / "v1"


def new_run(path, **kw) -> RunFile:
    return RunFile.create(
        path, protocol=FakeProtocol(), device_info=FakeDevice(), port="sim://?seed=1", operator="ada", **kw
    )


def test_flags_are_kept_as_sentences(tmp_path):
    path = str(tmp_path / "run.h5")
    flags = [
        "The rig streamed at 180 Hz, 10% below the commanded 200 Hz.",
        "Pressures moved less than the noise predicts, so the weight may not have been hung.",
    ]
    with new_run(path) as run:
        run.records.write({**make_record(1), "flags": flags})
        run.records.write(make_record(2))
    with RunFile.open(path) as run:
        assert run.records.read(1)["flags"] == flags
        assert run.records.read(2)["flags"] == []
        assert_record_stored(run.records.read(1), make_record(1))


@pytest.mark.parametrize(
    "flags, why",
    [
        (["two\nlines"], "flag 1 is more than one line"),
        (["fine.", ""], "flag 2 is empty"),
        ([3], "flag 1 is int, not text"),
    ],
)
def test_bad_flags_are_refused_and_nothing_written(tmp_path, flags, why):
    path = str(tmp_path / "run.h5")
    with new_run(path) as run:
        with pytest.raises(StoreError) as e:
            run.records.write({**make_record(1), "flags": flags})
        assert str(e.value) == f"trial 1 record: {why}; a flag is one sentence."
        assert run.records.ids() == []


def identity(device="mckibben-2dof", firmware="1.0"):
    return SimpleNamespace(device=device, firmware=firmware, channels=CHANNELS, gain=(0.001,) * 6, offset=(-0.25,) * 6)


def info(rig, **kw):
    base = dict(
        started="2026-11-24T01:00:00.000001+00:00",
        port="/dev/ttyACM0",
        baud=115200,
        rig=rig,
        operator="ada",
        command="labcli acquire run.h5 --port /dev/ttyACM0",
        resumed=False,
        other_rig=False,
    )
    return SimpleNamespace(**{**base, **kw})


def test_session_log_round_trip(tmp_path):
    path = str(tmp_path / "run.h5")
    with new_run(path) as run:
        assert run.sessions.rig_identity() is None  # no session yet: the caller falls back on the run's metadata
        run.sessions.begin(info(identity()))
        run.records.write(make_record(1))
        run.sessions.added(1)  # already logged with the record: not twice
        run.sessions.redone(2)
        run.records.write(make_record(2))
        run.sessions.skipped(3)
        run.sessions.end("quit")
    with RunFile.open(path, "a") as run:
        run.sessions.begin(info(identity(firmware="1.1"), baud=1_000_000, resumed=True, other_rig=True))
        run.records.write(make_record(3))
        # no end: a kill or a power cut
    with RunFile.open(path) as run:
        s1, s2 = run.sessions.all()
        rig = run.sessions.rig_identity()
    assert (s1["number"], s1["port"], s1["baud"], s1["device"], s1["firmware"]) == (
        1,
        "/dev/ttyACM0",
        115200,
        "mckibben-2dof",
        "1.0",
    )
    assert s1["channels"] == list(CHANNELS) and s1["calibration"]["offset"] == [-0.25] * 6
    assert (s1["added"], s1["redone"], s1["skipped"], s1["how"]) == ([1, 2], [2], [3], "quit")
    assert s1["started"] == "2026-11-24T01:00:00.000001+00:00" and s1["ended"] > s1["started"]
    assert s1["operator"] == "ada" and not s1["resumed"]
    assert (s2["baud"], s2["added"], s2["how"], s2["ended"], s2["resumed"], s2["other_rig"]) == (
        1_000_000,
        [3],
        None,
        "",
        True,
        True,
    )
    assert (rig.device, rig.firmware, tuple(rig.channels), tuple(rig.gain)) == (
        "mckibben-2dof",
        "1.1",
        CHANNELS,
        (0.001,) * 6,
    )


def test_session_end_is_checked(tmp_path):
    with new_run(str(tmp_path / "run.h5")) as run:
        with pytest.raises(StoreError) as e:
            run.sessions.end("finished")
        assert str(e.value) == f"no session is open in {tmp_path / 'run.h5'}; there is none to end."
        run.sessions.begin(info(identity()))
        with pytest.raises(StoreError) as e:
            run.sessions.end("bored")
        assert str(e.value).startswith("a session ends as one of finished, quit, interrupted")


def _close(value):
    """``value`` with every float made a ``pytest.approx`` (nested dicts and lists kept)."""
    if isinstance(value, dict):
        return {k: _close(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_close(v) for v in value]
    if isinstance(value, float):
        return pytest.approx(value, rel=1e-9, abs=1e-12)
    return value


@pytest.mark.parametrize("name", ["force", "pushes", "stretch", "joint"])
def test_version_1_files_read_as_labcli_0_1_read_them(invoke, name, tmp_path, monkeypatch):
    monkeypatch.chdir(ROOT)
    rel = f"tests/data/v1/{name}.h5"
    r = invoke("inspect", rel)
    assert r.exit_code == 0, r.output
    if name in ("force", "pushes"):
        # (The rPAM fixtures embed 0.1's rpam2015 protocol, whose Ogden constants today's protocol
        # check refuses, so their inspect no longer counts the planned grid; export stays exact.)
        # (today's inspect adds the baseline leak rate, which 0.1 did not print)
        lines = r.output.splitlines(keepends=True)
        leak = [i for i, line in enumerate(lines) if line.startswith("  leak ")]
        kept = [line for i, line in enumerate(lines) if not any(i in (j, j + 1) for j in leak)]
        assert "".join(kept) == (V1 / f"{name}.inspect.txt").read_text()
        r = invoke("inspect", "--json", rel)
        got = json.loads(r.output)
        got.pop("baseline_leak", None)
        # Sums in the drift figures may differ in the last bits between numpy releases.
        assert got == _close(json.loads((V1 / f"{name}.inspect.json").read_text()))
    r = invoke("export", rel, "-o", tmp_path / "out.csv")
    assert r.exit_code == 0, r.output
    got = (tmp_path / "out.csv").read_text()
    if got.startswith("trial,") or got.startswith("push,"):
        # Today's tables add the rest posture (theta1_0_deg, theta2_0_deg) from each
        # record's baseline angles, which 0.1 kept but did not export; the rest is unchanged.
        rows = [line.split(",") for line in got.splitlines()]
        rest = [rows[0].index("theta1_0_deg"), rows[0].index("theta2_0_deg")]
        got = "".join(",".join(v for i, v in enumerate(r) if i not in rest) + "\n" for r in rows)
    assert got == (V1 / f"{name}.csv").read_text()


def test_adding_to_a_version_1_file_copies_it_into_the_current_schema(tmp_path):
    path = str(tmp_path / "force.h5")
    shutil.copy(V1 / "force.h5", path)
    with RunFile.open(path) as run:
        before = run.records.table()
        ids = run.records.ids()
        models = run.models.all()
    with RunFile.open(path, "a") as run:
        assert run.version == SCHEMA_VERSION
        run.records.write(make_record(200))
    with RunFile.open(path) as run:
        assert run.records.ids() == ids + [200]
        assert run.records.table().iloc[: len(ids)].equals(before)
        assert run.models.all() == models
    with h5py.File(path, "r") as f:
        assert f["entry/labcli"].attrs["schema_version"] == SCHEMA_VERSION and "schema_version" not in f.attrs
    assert not [p for p in os.listdir(tmp_path) if p != "force.h5"]  # no partial file left behind


def test_sample_runs_still_read():
    for name in ("force", "pushes", "stretch", "joint"):
        with RunFile.open(ROOT / "sample_runs" / f"{name}.h5") as run:
            assert run.version in (2, 3, 4)  # as the sample runs were last written
            assert run.attrs["run_uid"] and run.attrs["start_time"] and run.attrs["protocol"]
            assert run.protocol_text and len(run.calibration()["gain"]) == len(run.channels)
            assert len(run.records.ids()) > 0
            assert len(run.records.table()) == len(run.records.ids())


def test_a_schema_2_file_reads_into_the_keys_of_schema_3(tmp_path):
    # Schema 2: metadata as /entry's attributes (variable-length strings), the protocol at
    # /entry/protocol, the calibration in each NXlog, the plan's set in a dataset plan_set.
    v2 = Path(__file__).resolve().parents[1] / "data" / "v2" / "float-counts.h5"
    with h5py.File(v2, "r") as f:
        assert "plan_set" in f["entry/trials"] and "kind" in f["entry"].attrs and "labcli" not in f["entry"]
    new = str(tmp_path / "new.h5")
    with new_run(new) as run:
        run.records.write(make_record(1))
    with RunFile.open(str(v2)) as old, RunFile.open(new) as now:
        assert (old.version, now.version) == (2, SCHEMA_VERSION)
        assert set(now.attrs) <= set(old.attrs) | {"creator_version"}, set(now.attrs) - set(old.attrs)
        assert old.attrs["kind"] == now.attrs["kind"] == "force" and old.attrs["imported"] is False
        assert old.protocol_text and list(old.calibration()["units"]) == list(now.calibration()["units"])
        assert "plan_set" in old.tables.records.names and "plan_set" in now.tables.records.names


def test_nexus_the_way_h5py_users_read_it(tmp_path):
    import datetime
    import uuid

    import numpy as np

    path = tmp_path / "deep" / "run.h5"
    path.parent.mkdir()
    with new_run(str(path)) as run:
        run.records.write(make_record(1))
        run.records.write(make_record(2))
    strings: list[str] = []
    units: dict[str, str] = {}
    with h5py.File(path, "r") as f:  # texts are fixed-length UTF-8: h5py gives them as bytes
        assert f.attrs["NX_class"] == b"NXroot" and f.attrs["file_name"] == b"run.h5"
        entry = f[f.attrs["default"].decode()]
        assert entry.attrs["NX_class"] == b"NXentry"
        # NeXus terms as NeXus fields; labcli's own items in an NXcollection
        assert uuid.UUID(entry["entry_identifier"][0].decode()).version == 4
        assert datetime.datetime.fromisoformat(entry["start_time"][0].decode()).utcoffset() is not None
        assert entry["program_name"][0] == b"labcli" and entry["program_name"].attrs["version"]
        assert entry["instrument/name"][0] == b"mckibben-2dof" and entry["user"].attrs["NX_class"] == b"NXuser"
        assert entry["labcli"].attrs["NX_class"] == b"NXcollection" and entry["labcli"].attrs["kind"] == b"force"
        assert set(entry["versions"].attrs) >= {"python", "numpy", "h5py", "hdf5", "labcli"}
        table = entry["trials"]
        assert table.attrs["NX_class"] == b"NXcollection"
        assert table["P"].attrs["units"] == b"MPa" and table["P"].shape == (2, 4)
        np.testing.assert_array_equal(table["P"][1], make_record(2)["P_MPa"])
        assert list(table["trial"][:]) == [1, 2]
        # the default plot: every channel logged over the run against device time, the raw log's own data
        plot = entry[entry.attrs["default"].decode()]
        assert plot.attrs["NX_class"] == b"NXdata" and plot.attrs["signal"] == b"values"
        assert list(plot.attrs["axes"]) == [b"time", b"channel"] and "auxiliary_signals" not in plot.attrs
        assert plot["values"] == entry["raw/values"] and plot["time"] == entry["raw/time"]  # the same datasets
        assert plot["values"].shape == (plot["time"].shape[0], len(CHANNELS))
        assert list(plot["channel"][:]) == list(range(len(CHANNELS))) and plot["time"].attrs["units"] == b"s"
        assert plot["channel"].attrs["long_name"] == ("channel: " + ", ".join(CHANNELS)).encode()
        # the plan's set is no NeXus set point (a field plan_set would be one): stored as plan_set_
        assert b"plan_set_" in list(table.attrs["columns"]) and "plan_set_" in table and "plan_set" not in table

        def visit(name, obj):
            for v in obj.attrs.values():
                strings.extend(str(x) for x in np.atleast_1d(v))
            if isinstance(obj, h5py.Dataset):
                if obj.dtype.kind != "S":  # a text has no unit
                    units[name] = obj.attrs["units"].decode()

        f.visititems(visit)
    # one unit per dataset, but the session log's calibration and the frames x channels arrays per
    # channel: each channel's (and each channel's NXlog has its own one)
    apart = ("entry/sessions/", "entry/plot/values")  # raw/values, visited by its link in the plot
    assert all("," not in u for k, u in units.items() if not k.startswith(apart)), units
    assert units["entry/plot/values"] == "MPa,MPa,MPa,MPa,rad,rad" and units["entry/raw/P_L1/value"] == "MPa"
    assert not [s for s in strings if str(tmp_path) in s]  # no path of the writer's machine


def test_a_schema_3_file_takes_new_records_in_its_own_layout(tmp_path):
    # Up to schema 3 each channel's values and counts are datasets of their own; a file of that
    # schema opened to add to keeps them (no frames x channels arrays appear) and reads as before.
    path = tmp_path / "force.h5"
    shutil.copy(ROOT / "tests" / "data" / "v3" / "force-before-marks.h5", path)
    with RunFile.open(path) as run:
        before, ids = run.records.table(), run.records.ids()
    rec = make_record(max(ids) + 1, n=300)
    with RunFile.open(path, "a") as run:
        assert run.version == 3
        run.records.write(rec)
    with RunFile.open(path) as run:
        assert run.records.ids() == [*ids, max(ids) + 1]
        assert run.records.table().iloc[: len(ids)].equals(before)
        assert_record_stored(run.records.read(max(ids) + 1), rec)
        assert run.verify()["ok"]
    with h5py.File(path, "r") as f:
        raw = f["entry/raw"]
        assert "values" not in raw and "counts" not in raw and not raw["P_L1/value"].is_virtual
        assert raw["P_L1/raw_value"].shape == raw["time"].shape


def test_raw_frames_rewritten_by_hand_fail_verify_never_a_traceback(tmp_path):
    """From schema 4 the readers read a channel's frames from raw/values and raw/counts (its NXlog's
    value and raw_value are views of them): either replaced, cut to one channel, fails verify."""
    path = tmp_path / "run.h5"
    with new_run(str(path)) as run:
        for i in (1, 2):
            run.records.write(make_record(i, n=120))
    good = path.read_bytes()
    for name in ("entry/raw/values", "entry/raw/counts"):
        path.write_bytes(good)
        with h5py.File(path, "r+") as f:
            data, attrs = f[name][()], dict(f[name].attrs)
            del f[name]
            f.create_dataset(name, data=data[:, :1])
            f[name].attrs.update(attrs)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", LabcliWarning)
            with RunFile.open(str(path)) as run:
                report = run.verify()
                assert run.records.ids() == [1, 2]  # the rows are whole: their windows are what is damaged
        assert not report["ok"] and report["records"] == 2 and report["windows"] == 0, report


def _rewrite(path: Path, name: str, how: str) -> None:
    """Replace dataset ``name`` by a copy cut to half its rows, of another type, or scaled 1000x."""

    with h5py.File(path, "r+") as f:
        data, attrs = f[name][()], dict(f[name].attrs)
        del f[name]
        if how == "shape":
            new = data[:, :1] if data.ndim == 2 else data[: len(data) // 2]
        elif how == "type":
            new = data.astype("S8")
        else:
            new = data * 1000.0
        f.create_dataset(name, data=new)
        f[name].attrs.update(attrs)


@pytest.mark.parametrize("how", ["shape", "type", "scale"])
@pytest.mark.parametrize("name", ["entry/trials/P", "entry/trials/theta", "entry/raw/P_L1/value", "entry/raw/seq"])
def test_a_dataset_rewritten_by_hand_is_caught_never_a_traceback(tmp_path, name, how):
    """A dataset replaced after the run was written (cut short, retyped, rescaled): every reading
    command ends in its own words, and ``inspect --verify`` names the damage."""
    from click.testing import CliRunner

    from labcli.cli import cli

    if name == "entry/raw/seq" and how != "shape":
        pytest.skip("frame numbers as text keep their values (read back the same), and scaled is not a type they take")
    run = tmp_path / "run.h5"
    shutil.copyfile(ROOT / "sample_runs" / "force.h5", run)
    with h5py.File(run, "r") as f:
        if f[name].is_virtual:
            pytest.skip(
                "from schema 4 a channel's value is a view of raw/values, what the readers read (rewritten above)"
            )
    _rewrite(run, name, how)
    model = ROOT / "sample_runs" / "force.model.json"
    # Rescaled trial columns leave every row failing its checksum: each reader says so in one
    # warning naming the rows and leaves them out (--verify lists them instead); a cut or retyped
    # dataset ends every command in an error and no warning.
    rows_damaged = how == "scale" and name.startswith("entry/trials/")
    # From schema 3 the default plot links raw/P_L1/value: the replaced dataset leaves the plot on
    # the old one, a new object among the file's metadata, which every reader warns of.
    with h5py.File(run, "r") as f:
        unlinked = name == "entry/raw/P_L1/value" and "entry/plot" in f
    for args in (
        ["inspect", run],
        ["export", run, "-o", tmp_path / "t.csv"],
        ["fit", run, "-o", tmp_path / "m.json"],
        ["validate", run, "--model", model],
        ["inspect", run, "--verify"],
    ):
        expected = (
            pytest.warns(LabcliWarning, match=r"run\.h5: 108 damaged records are left out \(row 0, trial 1")
            if rows_damaged and "--verify" not in args
            else pytest.warns(LabcliWarning, match=r"metadata .* do not match their checksum")
            if unlinked
            else contextlib.nullcontext()
        )
        with expected:
            result = CliRunner().invoke(cli, [str(a) for a in args])
        assert result.exception is None or isinstance(result.exception, SystemExit), (args, result.output)
        assert "Traceback" not in result.output
    # --verify names it: damaged records, or a table no run file keeps ("changed by another program").
    assert result.exit_code == 1 and ("damaged" in result.output or "changed by another program" in result.output), (
        result.output
    )


def test_counts_are_stored_as_integers_and_decimals_apart(tmp_path):
    """New files keep counts as int32; a window of decimals beside whole ones keeps both exactly."""
    import numpy as np

    from labcli.core.window import Window

    path = str(tmp_path / "run.h5")
    whole, decimal, after = make_record(1), make_record(2), make_record(3)
    w = decimal["raw"]["load"]
    decimal["raw"]["load"] = Window.of(w.seq, w.counts + 0.25, w.si, t_us=w.t_us)
    with new_run(path) as run:
        for rec in (whole, decimal, after):
            run.records.write(rec)
    with h5py.File(path) as f:
        assert f["entry/raw/P_L1/raw_value"].dtype == np.int32
    with RunFile.open(path) as run:
        report = run.verify()
        assert report["ok"] and report["windows"] == 6, report["problems"]
        for rec in (whole, decimal, after):
            back = run.records.read(rec["trial"])
            for key in ("baseline", "load"):
                np.testing.assert_array_equal(back["raw"][key].counts, rec["raw"][key].counts)
        assert run.records.read(1)["raw"]["load"].counts.dtype == np.int32
        assert run.records.read(2)["raw"]["load"].counts.dtype == np.float64


def test_a_schema_2_file_of_float64_counts_still_reads(tmp_path):
    """tests/data/v2/float-counts.h5, written before counts were stored as integers."""
    import numpy as np

    src = ROOT / "tests" / "data" / "v2" / "float-counts.h5"
    path = tmp_path / "old.h5"
    shutil.copy(src, path)
    with h5py.File(path) as f:
        assert f["entry/raw/P_L1/raw_value"].dtype == np.float64 and "raw_decimal" not in f["entry/raw/P_L1"]
    with RunFile.open(path) as run:
        assert run.records.ids() == [1, 2] and run.verify()["ok"]
        for i in (1, 2):
            back, want = run.records.read(i), make_record(i, n=40)
            for key in ("baseline", "load"):
                assert back["raw"][key].counts.dtype == np.int32
                np.testing.assert_array_equal(back["raw"][key].counts, want["raw"][key].counts)
    with RunFile.open(path, mode="a") as run:  # and takes more trials, in its own layout
        run.records.write(make_record(3, n=40))
    with RunFile.open(path) as run:
        np.testing.assert_array_equal(
            run.records.read(3)["raw"]["load"].counts, make_record(3, n=40)["raw"]["load"].counts
        )
