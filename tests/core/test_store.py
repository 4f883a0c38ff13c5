"""The HDF5 run file: round trips, units, refusals, open errors, resume."""

from __future__ import annotations

import datetime
import math
import os
import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest
from support.records import CHANNELS, FakeDevice, FakeProtocol, assert_record_stored, make_record

from labcli.core.store import SCHEMA_VERSION, RunFile, choose_split, import_table, to_edge
from labcli.core.window import Window
from labcli.errors import ConfigError, LabcliWarning, StoreError


def new_run(path, **kw) -> RunFile:
    return RunFile.create(
        path, protocol=FakeProtocol(), device_info=FakeDevice(), port="sim://?seed=1", operator="ada", **kw
    )


@pytest.fixture
def run_path(tmp_path):
    path = str(tmp_path / "run.h5")
    with new_run(path) as run:
        for i in range(1, 13):
            run.records.write(make_record(i))
    return path


def test_record_round_trip_values_and_dtypes(tmp_path):
    path = str(tmp_path / "run.h5")
    rec = make_record(3)
    with new_run(path) as run:
        run.records.write(rec)
    with RunFile.open(path) as run:
        assert run.records.ids() == [3]
        assert_record_stored(run.records.read(3), rec)
    with h5py.File(path, "r") as f:  # records are rows of run-wide columns, windows ranges of raw frames
        t, raw = f["entry/trials"], f["entry/raw"]
        assert t.attrs["committed"] == 1 and t["trial"][0] == 3
        assert t["P0"].shape == (1, 4) and t["F"].shape == (1, 2) and t["theta"].shape == (1, 2)
        assert t["P0"].attrs["units"] == b"MPa" and t["theta"].attrs["units"] == b"rad"
        assert t["mass"].attrs["units"] == b"kg" and t["F"].attrs["units"] == b"N"
        a, b = int(t["loaded_start"][0]), int(t["loaded_stop"][0])
        assert b - a == 50
        assert raw["time"].dtype == np.float64 and raw["seq"].dtype == np.uint64
        assert raw["P_L1/raw_value"].dtype == np.int32 and raw["P_L1/value"].attrs["units"] == b"MPa"
        assert raw["POT1/value"].attrs["units"] == b"rad"  # one unit per dataset, never comma-joined
        assert raw["P_L1"].attrs["NX_class"] == b"NXlog" and t.attrs["NX_class"] == b"NXcollection"


def test_large_raw_windows_are_compressed_and_read_back_exactly(tmp_path):
    path = str(tmp_path / "run.h5")
    big, small = make_record(1, n=200), make_record(2, n=50)
    with new_run(path) as run:
        run.records.write(big)
        run.records.write(small)
    with RunFile.open(path) as run:
        assert_record_stored(run.records.read(1), big)
        assert_record_stored(run.records.read(2), small)
    unfiltered, views, shuffled_floats, tables, small_chunks = [], {}, [], [], []

    def check(name: str, obj: object) -> None:
        if not isinstance(obj, h5py.Dataset):
            return
        if obj.is_virtual:  # a channel's column of raw/values or raw/counts: its bytes are theirs
            views[name] = obj.virtual_sources()
            return
        listed = [n.decode() if isinstance(n, bytes) else str(n) for n in obj.parent.attrs.get("columns", [])]
        # A table's column (and a split's ids): level 1, shuffled where whole numbers; numbers in
        # chunks of at most 64 bytes (a table written a row a commit) Fletcher32 alone.
        table = name.rsplit("/", 1)[-1] in [*listed, "checksum"] or name.endswith("split/ids")
        small = obj.chunks is not None and obj.dtype.kind != "S" and obj.dtype.itemsize * np.prod(obj.chunks) <= 64
        checksum = table and obj.dtype.kind == "u"  # 64 bits that look random: Fletcher32 alone, as small chunks
        if table and (small or checksum):
            if small:
                small_chunks.append(name)
            if obj.compression is not None or obj.shuffle or not obj.fletcher32:
                unfiltered.append(name)
            return
        if not (obj.compression == "gzip" and obj.fletcher32 and obj.chunks):
            unfiltered.append(name)
        if table:
            tables.append(name)
            if obj.compression_opts != 1 or obj.shuffle != (obj.dtype.kind in "iu"):
                shuffled_floats.append(name)
        elif not (obj.shuffle and obj.compression_opts == 4):  # raw windows and the rest: as before
            unfiltered.append(name)

    with h5py.File(path, "r") as f:
        f.visititems(check)
        assert f["entry/raw/values"].shape == (f["entry/raw/time"].shape[0], len(CHANNELS))
        assert f["entry/raw/counts"].dtype == np.int32
    assert unfiltered == [] and shuffled_floats == []
    assert any(t.endswith("/flags") for t in tables) and any(t.endswith("/trials/P0") for t in small_chunks)
    assert len(views) == 2 * len(CHANNELS)  # visited once each (the default plot links to the same ones)
    with h5py.File(path, "r") as f:  # what a reader with h5py alone sees: each channel's column, every frame
        raw = f["entry/raw"]
        for key, source in (("value", "/entry/raw/values"), ("raw_value", "/entry/raw/counts")):
            assert [(m.file_name, m.dset_name) for m in raw[f"P_R1/{key}"].virtual_sources()] == [(".", source)]
        for j, c in enumerate(CHANNELS):
            np.testing.assert_array_equal(raw[f"{c}/value"][:], raw["values"][:, j])
            np.testing.assert_array_equal(raw[f"{c}/raw_value"][:], raw["counts"][:, j])
            assert raw[f"{c}/raw_value"].dtype == np.int32 and raw[f"{c}/value"].maxshape == (None,)


def test_every_dataset_has_units(run_path):
    with RunFile.open(run_path, "a") as run:
        run.split.set([1, 2], [3], "sequential")
        run.models.record("takuma", '{"a": 1}')
    missing, texts_with_units = [], []

    def check(name: str, obj: object) -> None:
        if not isinstance(obj, h5py.Dataset):
            return
        if obj.dtype.kind in "iuf" and not str(obj.attrs.get("units", "")):  # a number has a unit ('1' for none)
            missing.append(name)
        if obj.dtype.kind == "S" and "units" in obj.attrs:  # a text has none
            texts_with_units.append(name)

    with h5py.File(run_path, "r") as f:
        f.visititems(check)
        n = []
        f.visititems(lambda name, obj: n.append(name) if isinstance(obj, h5py.Dataset) else None)
    assert missing == [] and texts_with_units == []
    assert len(n) > 12 * 8  # the check above did visit the windows


def test_root_metadata(run_path):
    with RunFile.open(run_path) as run:
        a = run.attrs
        assert a["schema"] == "labcli-run" and a["schema_version"] == SCHEMA_VERSION
        assert a["kind"] == "force" and a["protocol"] == "bench"
        assert (a["device"], a["firmware"], a["port"], a["operator"]) == (
            "mckibben-2dof",
            "1.0",
            "sim://?seed=1",
            "ada",
        )
        assert a["channels"] == list(CHANNELS)
        started = datetime.datetime.fromisoformat(a["started"])  # ISO 8601, microseconds and UTC offset
        assert started.utcoffset() is not None and "." in a["started"]
        assert run.protocol_text == FakeProtocol().text
        cal = run.calibration()
        # P = (c*5/4095 - 1)/4 MPa: gain 5/(4*4095) MPa/count, offset -0.25 MPa
        assert cal["gain"][0] == pytest.approx(5 / (4 * 4095), rel=1e-12)
        assert cal["offset"][0] == pytest.approx(-0.25, rel=1e-12)
        assert cal["gain"][5] == pytest.approx(math.radians(340 / 4095), rel=1e-9)
        assert cal["units"] == ("MPa",) * 4 + ("rad",) * 2


def test_trial_table_columns_and_units(run_path):
    with RunFile.open(run_path, "a") as run:
        run.split.set([1, 2, 3], [4], "manual")
        df = run.records.table()
    assert list(df.columns) == [
        "trial",
        "set",
        "P_L10",
        "P_R10",
        "P_L20",
        "P_R20",
        "P_L1",
        "P_R1",
        "P_L2",
        "P_R2",
        "theta1_deg",
        "theta2_deg",
        "Fx_N",
        "Fy_N",
        "mass_g",
        "direction_deg",
        "theta1_0_deg",
        "theta2_0_deg",
    ]
    assert df["trial"].tolist() == list(range(1, 13))
    assert df["set"].tolist()[:5] == ["fit", "fit", "fit", "validation", ""]
    rec = make_record(7)
    row = df[df.trial == 7].iloc[0]
    assert row["theta2_deg"] == pytest.approx(math.degrees(rec["theta_rad"][1]), rel=1e-11)
    assert row["mass_g"] == pytest.approx(rec["mass_kg"] * 1e3)
    assert row["direction_deg"] == 15.0 * 7
    assert row["P_R20"] == rec["P0_MPa"][3] and row["Fy_N"] == rec["force_N"][1]
    # the rest posture is the record's baseline potentiometer angles, in degrees
    assert row["theta1_0_deg"] == pytest.approx(math.degrees(rec["pot0_rad"][0]), rel=1e-11)
    assert row["theta2_0_deg"] == pytest.approx(math.degrees(rec["pot0_rad"][1]), rel=1e-11)


def test_edge_rounding_makes_degrees_round_trip_exact():
    rng = np.random.default_rng(5)
    typed = np.round(rng.uniform(-180, 180, 2000), 6)
    back = to_edge(np.degrees(np.radians(typed)))
    assert np.array_equal(back, typed)
    # without the edge rounding some values do not come back bit for bit
    assert not np.array_equal(np.degrees(np.radians(typed)), typed)


def test_overwrite_refused_with_exact_message(run_path):
    with pytest.raises(StoreError) as e:
        new_run(run_path)
    assert str(e.value) == f"{run_path} already exists; continue it with --resume, or pass --force to overwrite it."
    with RunFile.open(run_path) as run:
        assert len(run.records.ids()) == 12
    with new_run(run_path, force=True) as run:
        assert run.records.ids() == []


def test_open_missing(tmp_path):
    path = str(tmp_path / "nope.h5")
    with pytest.raises(StoreError) as e:
        RunFile.open(path)
    assert str(e.value) == f"{path} does not exist; check the path."


def test_open_not_hdf5(tmp_path):
    path = tmp_path / "trials.csv"
    path.write_text("trial,set\n1,fit\n")
    with pytest.raises(StoreError) as e:
        RunFile.open(str(path))
    assert str(e.value) == (
        f"{path} is not an HDF5 file; run files are written by 'labcli acquire' or 'labcli import'."
    )


def test_open_other_schema(tmp_path):
    path = str(tmp_path / "other.h5")
    with h5py.File(path, "w") as f:
        f.create_dataset("x", data=[1, 2, 3])
    with pytest.raises(StoreError) as e:
        RunFile.open(path)
    assert str(e.value) == (
        f"{path} is an HDF5 file but not a labcli run file (no schema attribute, expected 'labcli-run')."
    )
    with h5py.File(path, "a") as f:
        f.attrs["schema"] = "nexus-scan"
    with pytest.raises(StoreError) as e:
        RunFile.open(path)
    assert str(e.value) == (
        f"{path} is an HDF5 file but not a labcli run file (schema 'nexus-scan', expected 'labcli-run')."
    )


def test_open_newer_schema(run_path):
    with h5py.File(run_path, "a") as f:
        f["entry/labcli"].attrs["schema_version"] = SCHEMA_VERSION + 1
    with pytest.raises(StoreError) as e:
        RunFile.open(run_path)
    assert str(e.value) == (
        f"{run_path} uses run-file schema version {SCHEMA_VERSION + 1}, newer than this "
        f"labcli reads ({SCHEMA_VERSION}); upgrade labcli."
    )


@pytest.mark.parametrize("keep", [0.5, 0.9])
def test_open_truncated(run_path, tmp_path, keep):
    cut = str(tmp_path / "cut.h5")
    size = os.path.getsize(run_path)
    with open(run_path, "rb") as src, open(cut, "wb") as dst:
        dst.write(src.read(int(size * keep)))
    with pytest.raises(StoreError) as e:
        RunFile.open(cut)
    assert str(e.value) == f"{cut} is damaged or truncated and HDF5 cannot open it; use a backup copy."


def leave_uncommitted_row(path: str, trial: int, garbage: float) -> None:
    """What a kill between writing a row and committing it leaves: a row past ``@committed``."""
    with h5py.File(path, "a") as f:
        t = f["entry/trials"]
        n = int(t.attrs["committed"])
        for name, ds in t.items():
            if isinstance(ds, h5py.Dataset) and ds.shape[0] <= n:
                ds.resize(n + 1, axis=0)
        t["trial"][n] = trial
        t["P0"][n] = [garbage] * 4


def test_incomplete_trial_ignored_then_superseded_on_resume(run_path):
    leave_uncommitted_row(run_path, 13, 9.0)
    with RunFile.open(run_path, "a") as run:
        assert run.records.ids() == list(range(1, 13))
        assert 13 not in run.records.table()["trial"].tolist()
        assert run.records.first_incomplete(range(1, 20)) == 13
        run.records.write(make_record(13))
        assert run.records.incomplete_ids() == []
        assert run.records.first_incomplete(range(1, 20)) == 14
    with RunFile.open(run_path) as run:
        assert run.records.first_incomplete(range(1, 14)) is None
        assert_record_stored(run.records.read(13), make_record(13))
        assert run.summary()["complete"] == 13
    with h5py.File(run_path, "r") as f:
        assert f["entry/trials"].attrs["committed"] >= 13


def test_complete_trial_never_overwritten(run_path):
    with RunFile.open(run_path, "a") as run:
        with pytest.raises(StoreError) as e:
            run.records.write(make_record(5))
        assert str(e.value) == f"trial 5 is already complete in {run_path}; a stored record is never overwritten."
        assert_record_stored(run.records.read(5), make_record(5))


def test_bad_record_writes_nothing(run_path):
    rec = make_record(20)
    rec["P_MPa"] = [0.1, 0.2, 0.3]
    with RunFile.open(run_path, "a") as run:
        with pytest.raises(StoreError) as e:
            run.records.write(rec)
        assert str(e.value) == (
            "trial 20 record: 'P_MPa' must hold 4 values (loaded pressures P_L1,P_R1,P_L2,P_R2 in MPa), got shape (3,)."
        )
        rec = make_record(20)
        w = rec["raw"]["load"]
        rec["raw"]["load"] = Window.of(w.seq, w.counts[:, :5], w.si, t_us=w.t_us)
        with pytest.raises(StoreError, match=r"the loaded window must hold n frames of 6 channels"):
            run.records.write(rec)
        assert run.records.incomplete_ids() == [] and 20 not in run.records.ids()


def test_read_only_refuses_writes(run_path):
    with RunFile.open(run_path) as run:
        with pytest.raises(StoreError) as e:
            run.records.write(make_record(30))
    assert str(e.value) == f"{run_path} is open read-only; open it with mode 'a' to add records."


def test_decimal_counts_kept_exactly(tmp_path):
    rec = make_record(2)
    w = rec["raw"]["load"]
    rec["raw"]["load"] = Window.of(w.seq, w.counts + 0.25, w.si, t_us=w.t_us)
    with new_run(str(tmp_path / "d.h5")) as run:
        run.records.write(rec)
        back = run.records.read(2)
    assert back["raw"]["load"].counts.dtype == np.float64
    np.testing.assert_array_equal(back["raw"]["load"].counts, rec["raw"]["load"].counts)


def test_recording_order_not_id_order(tmp_path):
    with new_run(str(tmp_path / "o.h5")) as run:
        for i in (5, 2, 9, 1):
            run.records.write(make_record(i))
        assert run.records.ids() == [5, 2, 9, 1]
        assert choose_split(run.records.ids(), 2, 1) == ([5, 2], [9])


def test_choose_split_random_is_seeded_and_disjoint():
    ids = list(range(100, 208))
    f1, v1 = choose_split(ids, 90, 18, "random", 7)
    f2, v2 = choose_split(ids, 90, 18, "random", 7)
    f3, _ = choose_split(ids, 90, 18, "random", 8)
    assert (f1, v1) == (f2, v2) and f1 != f3
    assert len(f1) == 90 and len(v1) == 18 and not set(f1) & set(v1)
    assert f1 == sorted(f1)
    with pytest.raises(ConfigError) as e:
        choose_split(ids[:100], 90, 18)
    assert str(e.value) == "the run has 100 completed trials, fewer than the 108 asked for (90 fit + 18 validation)."


def test_set_split_checks_ids(run_path):
    with RunFile.open(run_path, "a") as run:
        with pytest.raises(StoreError, match=r"^trial 3 cannot be in both the fit and the validation set\.$"):
            run.split.set([1, 3], [3])
        with pytest.raises(StoreError, match=r"^trial 44 is not a complete trial in .*run\.h5, so it cannot join"):
            run.split.set([1, 44], [2])
        s = run.split.assign(8, 4, "random", 3)
        assert s["strategy"] == "random" and s["seed"] == 3
        assert sorted(s["fit"] + s["validation"]) == list(range(1, 13))


def test_models_round_trip(run_path):
    with RunFile.open(run_path, "a") as run:
        run.models.record("takuma2014", '{"beta_Fx1": 1.5}')
        run.models.record("takuma2014", '{"beta_Fx1": 2.5}')
    with RunFile.open(run_path) as run:
        assert run.models.all() == {"takuma2014": '{"beta_Fx1": 2.5}'}


def test_plan_stored_as_columns(tmp_path):
    plan = {"trial": [1, 2], "set": ["fit", "validation"], "mass_g": [200.0, 150.5], "direction_deg": [0.0, 90.0]}
    with new_run(str(tmp_path / "p.h5"), plan=plan) as run:
        df = run.plan_table()
    assert df.to_dict("list") == plan
    with h5py.File(str(tmp_path / "p.h5"), "r") as f:
        assert f["entry/plan/mass_g"].attrs["units"] == b"g" and f["entry/plan/direction_deg"].attrs["units"] == b"deg"
        assert f["entry/plan/trial"].dtype == np.int64


def test_push_run_round_trip(tmp_path):
    proto = FakeProtocol(name="bench-push", kind="push")
    path = str(tmp_path / "push.h5")
    rec = make_record(1)
    push = {
        "push": 3,
        "object": "can-al-1",
        "R_m": 0.033,
        "d_m": 0.008,
        "phi_rad": None,
        "category": "medium",
        "true_stiffness_N_per_m": 2500.0,
        "P0_MPa": rec["P0_MPa"],
        "P_MPa": rec["P_MPa"],
        "raw": rec["raw"],
        "settle": rec["settle"],
    }
    with RunFile.create(path, protocol=proto, device_info=FakeDevice()) as run:
        run.records.write(push)
        run.records.write({**push, "push": 4, "phi_rad": math.radians(10.0), "true_stiffness_N_per_m": None})
    with RunFile.open(path) as run:
        assert run.kind == "push" and run.records.ids() == [3, 4]
        back = run.records.read(3)
        assert math.isnan(back["phi_rad"]) and back["R_m"] == 0.033 and back["object"] == "can-al-1"
        np.testing.assert_array_equal(back["raw"]["load"].si, rec["raw"]["load"].si)
        df = run.records.table()
    assert list(df.columns) == [
        "push",
        "object",
        "R_m",
        "d_m",
        "phi_deg",
        "P_L10",
        "P_R10",
        "P_L20",
        "P_R20",
        "P_L1",
        "P_R1",
        "P_L2",
        "P_R2",
        "category",
        "true_stiffness_N_per_m",
    ]
    assert math.isnan(df.phi_deg[0]) and df.phi_deg[1] == 10.0
    assert df.true_stiffness_N_per_m[0] == 2500.0 and math.isnan(df.true_stiffness_N_per_m[1])


def test_import_table_round_trip_and_refusal(run_path, tmp_path):
    with RunFile.open(run_path, "a") as run:
        run.split.set(list(range(1, 10)), [10, 11], "sequential")
        df = run.records.table()
    df["operator_note"] = ["ok"] * 12
    df["rep"] = list(range(12))
    out = str(tmp_path / "imp.h5")
    with import_table(df, out, protocol=FakeProtocol(), source="t.csv") as run:
        assert run.attrs["imported"] is True and run.attrs["source"] == "t.csv"
        assert run.split.get()["strategy"] == "imported"
        back = run.records.table()
        assert run.records.read(4)["raw"] == {} and run.records.read(4)["accepted"] == "imported"
    assert back.equals(df)
    with pytest.raises(StoreError) as e:
        import_table(df, out, protocol=FakeProtocol())
    assert str(e.value) == f"{out} already exists; use --force to overwrite it."
    bad = df.copy()
    bad.loc[3, "set"] = "train"
    before = os.path.getsize(out)
    with pytest.raises(ConfigError) as e:
        import_table(bad, out, protocol=FakeProtocol(), force=True)
    assert str(e.value) == "trial 4: set must be fit, validation or empty, got 'train'."
    assert os.path.getsize(out) == before and not os.path.exists(out + ".importing")


def test_summary_drift_and_settling(tmp_path):
    path = str(tmp_path / "s.h5")
    with new_run(path) as run:
        for i in range(10):
            rec = make_record(i)
            rec["P0_MPa"] = np.array([0.2 + 0.0005 * i, 0.2, 0.2 - 0.001 * i, 0.2])  # 0.5 kPa/trial, -1 kPa/trial
            run.records.write(rec)
        s = run.summary()
    d = s["baseline_drift"]
    assert d["P_L1"]["slope_kPa_per_trial"] == pytest.approx(0.5)
    assert d["P_L2"]["slope_kPa_per_trial"] == pytest.approx(-1.0)
    assert d["P_L2"]["max_deviation_kPa"] == pytest.approx(9.0)
    assert d["P_R1"]["max_deviation_kPa"] == 0.0
    assert d["P_L1"]["first_MPa"] == 0.2 and d["P_L1"]["last_MPa"] == pytest.approx(0.2045)
    times = [2.0 + (i % 4) for i in range(10)]
    assert s["settle"]["median_s"] == float(np.median(times)) and s["settle"]["max_s"] == 5.0
    assert s["settle"]["timeout_ids"] == [4, 9] and s["settle"]["timeout_accepted"] == 2
    assert s["complete"] == 10 and s["incomplete"] == 0 and s["planned"] is None


def test_file_is_default_libver_and_reopens_for_append(run_path):
    with h5py.File(run_path, "r") as f:
        assert f.libver[0] == "earliest"
    with RunFile.open(run_path, "a") as run:
        run.records.write(make_record(40))
    shutil.copy(run_path, run_path + ".copy")
    with RunFile.open(run_path + ".copy") as run:
        assert run.records.ids()[-1] == 40


@pytest.mark.parametrize("torn", ["metadata", "records", "split"])
@pytest.mark.parametrize("writer", ["holds the file", "let go while it was read"])
def test_a_reader_that_meets_a_commit_under_way_reads_the_run_again_as_the_schema_it_is(
    run_path, monkeypatch, torn, writer
):
    """A torn read while a writer holds the file (its metadata, its record table or its split, read
    while a checkpoint copies HDF5's pages in) makes the reader open the file again: it must read the
    tables again, not take a schema-3 run for a schema-1 one, whose group-per-record layout it lacks
    (0 trials).  A writer that held the file when the reader opened it and has let go since (its
    last commit tore the read, then it closed) counts as one at work."""
    from labcli.core.store import records, runfile, space, split

    opened = []  # the writer let go once HDF5 had opened the file
    real_open = runfile.h5open
    monkeypatch.setattr(runfile, "h5open", lambda path, mode: opened.append(path) or real_open(path, mode))
    holds = (lambda path: True) if writer == "holds the file" else (lambda path: not opened)
    monkeypatch.setattr(space, "writer_holds", holds)
    with RunFile.open(run_path, "a") as run:
        run.split.set(range(1, 9), range(9, 13))
    # What was read through the first opening is torn; the file opened again reads whole.
    if torn == "split":
        real_split = split.read_split

        def torn_split(t):
            got = real_split(t)
            return (got[0], ["split row 0: its checksum does not match its values"]) if len(opened) < 2 else got

        monkeypatch.setattr(split, "read_split", torn_split)
    elif torn == "metadata":
        real_ok = runfile.metadata_ok
        monkeypatch.setattr(runfile, "metadata_ok", lambda f: len(opened) > 1 and real_ok(f))
    else:
        real_read = records.from_v2

        def torn_records(t, rt):
            if len(opened) < 2:
                raise OSError("Can't read data (wrong B-tree signature)")
            return real_read(t, rt)

        monkeypatch.setattr(records, "from_v2", torn_records)
    with RunFile.open(run_path) as run:
        assert run.version == SCHEMA_VERSION
        assert run.records.ids() == list(range(1, 13))
        assert run.records.table()["trial"].tolist() == list(range(1, 13))
        assert run.split.set_of() == {i: "fit" if i < 9 else "validation" for i in range(1, 13)}
    assert len(opened) == 2  # the torn read was met, and the file read again once


@pytest.mark.parametrize("torn", ["window", "frames", "attrs", "metadata", "calibration", "plan"])
@pytest.mark.parametrize("writer", ["holds the file", "let go while it was read"])
def test_a_reader_that_meets_a_commit_under_way_reads_windows_and_metadata_again(tmp_path, monkeypatch, torn, writer):
    """A trial's raw frames and the run's metadata (its attributes, NeXus fields, calibration and
    plan), read while a writer's checkpoint copies HDF5's pages in, are read again with the file
    opened afresh: a torn read is neither a damaged window left out with a warning nor a sentence
    saying the metadata cannot be read."""
    from labcli.core.store import frames, runfile, space
    from labcli.core.store.columns import Table

    path = str(tmp_path / "run.h5")
    plan = {"trial": [1, 2], "set": ["fit", "validation"], "mass_g": [200.0, 150.5], "direction_deg": [0.0, 90.0]}
    rec = make_record(3)
    with new_run(path, plan=plan) as run:
        run.records.write(rec)
    opened = []  # the writer let go once HDF5 had opened the file
    real_open = runfile.h5open
    monkeypatch.setattr(runfile, "h5open", lambda path, mode: opened.append(path) or real_open(path, mode))
    holds = (lambda path: True) if writer == "holds the file" else (lambda path: not opened)
    monkeypatch.setattr(space, "writer_holds", holds)

    def first_opening() -> bool:  # what is read through the first opening is torn
        return len(opened) < 2

    def raise_when_torn(real):
        def read(*a):
            if first_opening():
                raise OSError("Can't read data (wrong B-tree signature)")
            return real(*a)

        return read

    with RunFile.open(path) as run:
        cols = run.records.columns().cols
        a, b = int(cols["loaded_start"][0]), int(cols["loaded_stop"][0])
        if torn in ("window", "frames"):
            real_rows = frames.read_rows

            def torn_rows(ds, a, b):
                values, bad = real_rows(ds, a, b)
                return values, bad | first_opening()

            monkeypatch.setattr(frames, "read_rows", torn_rows)
        elif torn == "attrs":
            monkeypatch.setattr(runfile, "plain", raise_when_torn(runfile.plain))
        elif torn == "metadata":
            monkeypatch.setattr(runfile, "read_metadata", raise_when_torn(runfile.read_metadata))
        elif torn == "calibration":  # the units are read in frames (from raw/values), the rest in runfile
            monkeypatch.setattr(runfile, "text", raise_when_torn(runfile.text))
            monkeypatch.setattr(frames, "text", raise_when_torn(frames.text))
        else:

            class TornPlan(Table):
                def read(self, *a, **kw):
                    got = super().read(*a, **kw)
                    if first_opening():
                        got.damaged = [(0, "its checksum does not match its values")]
                    return got

            monkeypatch.setattr(runfile, "Table", TornPlan)
        if torn == "window":
            assert_record_stored(run.records.read(3), rec)
        elif torn == "frames":
            stored, w = rec["raw"]["load"], run.windows.frames(a, b)
            assert np.array_equal(w.seq, stored.seq) and np.array_equal(w.si, stored.si)
        elif torn in ("attrs", "metadata"):
            attrs = run.attrs
            assert attrs["operator"] == "ada" and attrs["schema_version"] == SCHEMA_VERSION
        elif torn == "calibration":
            assert run.calibration()["units"] == ("MPa",) * 4 + ("rad",) * 2
        else:
            assert run.plan_table().to_dict("list") == plan
    assert len(opened) == 2  # the torn read was met, and the file read again once


@pytest.mark.parametrize("table", ["split", "models", "sessions"])
def test_a_log_table_hdf5_cannot_read_is_one_sentence(run_path, monkeypatch, table):
    """A bit flip in a table's header can make HDF5 (or the table's own reader) fail in any way (the
    metadata campaign met KeyError: 'strategy' in the split): with no writer about, one sentence
    naming the table, never the exception."""
    from labcli.core.store import models, sessions, split

    module, name = {
        "split": (split, "read_split"),
        "models": (models, "read_models"),
        "sessions": (sessions, "read_sessions"),
    }[table]

    def damaged(t):
        raise KeyError("strategy")

    monkeypatch.setattr(module, name, damaged)
    said = {"split": "its split", "models": "its recorded models", "sessions": "its session log"}[table]
    with RunFile.open(run_path) as run:
        with pytest.raises(StoreError) as e:
            {"split": run.split.get, "models": run.models.all, "sessions": run.sessions.all}[table]()
        assert str(e.value) == (
            f"{run_path}: {said} cannot be read (damaged); check the file with labcli inspect --verify and use a "
            "backup copy."
        )
        assert f"{table}: {run_path}: {said} cannot be read" in " ".join(run.verify()["problems"])


def test_torn_uncommitted_row_is_ignored_and_written_over(run_path):
    """A kill mid-write can leave any bytes past ``@committed``: never read, and the next commit goes on."""
    leave_uncommitted_row(run_path, 5, float("nan"))  # a repeated id and nonsense values: never counted
    with RunFile.open(run_path, "a") as run:
        assert run.records.ids() == list(range(1, 13))
        run.records.write(make_record(13))
    with RunFile.open(run_path) as run:
        assert run.records.table()["trial"].tolist() == list(range(1, 14))
        assert_record_stored(run.records.read(5), make_record(5))
        assert_record_stored(run.records.read(13), make_record(13))


def chunk_offset(path: str, dataset: str, row: int) -> int:
    """Where in the file the chunk holding ``row`` of ``dataset`` (one row per chunk here) starts."""
    with h5py.File(path, "r") as f:
        ds = f[dataset]
        return ds.id.get_chunk_info_by_coord((row,) + (0,) * (ds.ndim - 1)).byte_offset


def test_a_damaged_record_is_named_and_left_out(run_path):
    """One flipped byte in trial 4's pressures: trial 4 is named in a warning, the others read as written."""
    offset = chunk_offset(run_path, "entry/trials/P", 3)
    with open(run_path, "r+b") as fh:
        fh.seek(offset + 4)
        b = fh.read(1)
        fh.seek(offset + 4)
        fh.write(bytes([b[0] ^ 0x10]))
    with pytest.warns(LabcliWarning) as caught:
        with RunFile.open(run_path) as run:
            ids = run.records.ids()
            for i in ids:
                assert_record_stored(run.records.read(i), make_record(i))
            report = run.verify()
    assert ids == [1, 2, 3, *range(5, 13)]
    assert any("trial 4" in str(w.message) and "damaged" in str(w.message) for w in caught)
    assert not report["ok"] and any("trial 4" in p for p in report["problems"])


def test_a_new_split_is_in_force_and_the_old_one_kept(run_path):
    with RunFile.open(run_path, "a") as run:
        run.split.assign(8, 4, "random", 1)
        first = run.split.get()
    with RunFile.open(run_path, "a") as run:
        run.split.assign(8, 4, "random", 2)
        second = run.split.get()
    with h5py.File(run_path, "r") as f:  # splits are appended: the history stays, the last is in force
        assert f["entry/split"].attrs["committed"] == 2
    assert first["fit"] != second["fit"] and second["seed"] == 2
    assert sorted(second["fit"] + second["validation"]) == list(range(1, 13))


def test_checksums_of_repeated_fill_and_of_one_long_entry_equal_the_spelt_out_fold():
    import numpy as np

    from labcli.core.store import checksum as c

    def reference(parts, positions):
        h = c._BASIS ^ (positions.astype(np.uint64) * c._STEP)
        for part in parts:
            w = c.words(part, len(positions))
            for j in range(w.shape[1]):
                h = (h ^ w[:, j]) * c._PRIME
        return h

    n = 777
    positions = np.arange(5, 5 + n, dtype=np.uint64)
    spelt = [np.zeros(n, dtype="S1024"), np.full(n, b"imported", dtype="S40"), np.full((n, 2), np.nan), np.arange(n)]
    repeated = [c.Repeated(a[:1], n) for a in spelt[:3]] + [spelt[3]]
    assert (c.fold(repeated, positions) == reference(spelt, positions)).all()
    blob = [np.arange(20_000, dtype=np.int64).view(np.uint8).reshape(1, -1)]
    one = np.array([3], dtype=np.uint64)
    assert c.fold(blob, one)[0] == reference(blob, one)[0]
    flipped = blob[0].copy()
    flipped[0, 12345] ^= 4
    assert c.fold([flipped], one)[0] != c.fold(blob, one)[0]


def test_a_bulk_import_leaves_columns_without_values_unwritten_and_they_read_as_their_fill(run_path, tmp_path):
    with RunFile.open(run_path, "a") as run:
        df = run.records.table()
    out = str(tmp_path / "imp.h5")
    with import_table(df, out, protocol=FakeProtocol(), source="t.csv") as run:
        assert run.verify()["ok"] is True
        back = run.records.table()
        rec = run.records.read(int(df.trial[0]))
        assert rec["flags"] == [] and rec["accepted"] == "imported"
    assert back.equals(df)
    with h5py.File(out, "r") as f:
        rows = f["entry/trials"]
        assert rows["flags"].shape[0] >= len(df) and rows["flags"].id.get_storage_size() == 0
        assert rows["trial"].id.get_storage_size() > 0


def test_the_readers_never_open_the_channels_views(tmp_path):
    # HDF5 keeps a virtual dataset's mappings in the global heap and reads them as it opens the
    # dataset; one flipped bit there crashed or hung HDF5 (2 of 40 single flips).  labcli reads
    # raw/values and raw/counts, never the NXlog views of them: with every view made a link that
    # fails when followed, every reader and verify read the run as before.
    from support import procs

    path = tmp_path / "run.h5"
    recs = [make_record(i, n=150) for i in (1, 2)]
    with new_run(str(path)) as run:
        for rec in recs:
            run.records.write(rec)
    with h5py.File(path, "r+") as f:
        for c in CHANNELS:
            for key in ("value", "raw_value"):
                assert f[f"entry/raw/{c}/{key}"].is_virtual
                del f[f"entry/raw/{c}/{key}"]
                f[f"entry/raw/{c}/{key}"] = h5py.ExternalLink("no-such-file.h5", "/nothing")
    r = procs.labcli("inspect", "--verify", "run.h5", cwd=tmp_path)
    assert r.returncode == 0 and r.stderr == "", r.stdout + r.stderr
    with RunFile.open(str(path)) as run:
        for rec in recs:
            assert_record_stored(run.records.read(rec["trial"]), rec)
        assert run.calibration()["units"] == ("MPa",) * 4 + ("rad",) * 2
    with h5py.File(path, "r") as f, pytest.raises(KeyError):
        f["entry/raw/P_L1/value"]  # noqa: B018 - what opening a view meets here
    # The whole global heap overwritten (where the views' mappings are): HDF5's object visit fails
    # on it (it reads every dataset's layout; one flipped bit there hung it), the link visit the
    # metadata checksum takes does not, so verify and every reader read the run as written.
    with new_run(str(path), force=True) as run:
        run.records.write(recs[0])
    data = bytearray(path.read_bytes())
    assert data.count(b"GCOL") == 1
    at = data.index(b"GCOL")
    data[at + 16 : at + 4096] = b"\xff" * (4096 - 16)  # every object of the collection, past its header
    path.write_bytes(bytes(data))
    with h5py.File(path, "r") as f, pytest.raises(RuntimeError):
        f.visit(lambda name: None)
    r = procs.labcli("inspect", "--verify", "run.h5", cwd=tmp_path)
    assert r.returncode == 0 and r.stderr == "", r.stdout + r.stderr
    r = procs.labcli("export", "run.h5", "-o", "t.csv", cwd=tmp_path)
    assert r.returncode == 0 and r.stderr == "", r.stderr


@pytest.mark.parametrize("name", ["v1/force.h5", "v2/float-counts.h5", "v3/force-before-marks.h5", "new"])
def test_the_metadata_checksum_names_every_object_as_visit_does(tmp_path, name):
    # The checksum walks the links (opening._objects), not HDF5's object visit: the same objects
    # under the same names in the same order, so every file's checksum is what it was.
    from labcli.core.store.opening import _objects

    path = tmp_path / "run.h5"
    if name == "new":
        with new_run(str(path)) as run:
            run.records.write(make_record(1, n=50))
    else:
        shutil.copy(Path(__file__).resolve().parents[1] / "data" / name, path)
    with h5py.File(path, "r") as f:
        names: list[str] = []
        f.visit(names.append)
        assert _objects(f) == names and len(names) > 40
