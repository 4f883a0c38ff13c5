"""The benchmarks measure what they say: each option changes what runs, each baseline does the work it stands for.

No timing here (no test asserts a time): call counts, files and numbers.  A benchmark option
that stopped reaching the code (bench_store's "no fsync" row once set an attribute RunFile no
longer read, and measured the fsync path twice) fails one of these.
"""

from __future__ import annotations

import importlib
import json
import os
import re
import subprocess
import sys
from pathlib import Path
from types import ModuleType

import h5py
import numpy as np
import pandas as pd
import pytest

from labcli.core.protocol import load_protocol
from labcli.core.store import RunFile
from labcli.papers.takuma2014.models.metrics import evaluate
from labcli.papers.takuma2014.models.synthetic import paper_trials
from labcli.papers.takuma2014.models.takuma import TERMS, TakumaModel

HERE = Path(__file__).resolve().parent
RIG = dict(load_protocol("takuma2014").settings.rig)


def bench(name: str) -> ModuleType:
    sys.path.insert(0, str(HERE))
    return importlib.import_module(name)


def baseline(script: str, *args: object) -> str:
    """A baseline script's stdout (it imports no labcli: run as the benchmark runs it)."""
    out = subprocess.run(
        [sys.executable, str(HERE / "baselines" / script), *map(str, args)], capture_output=True, text=True, check=True
    )
    return out.stdout


# --------------------------------------------------------------------------- bench_store


def test_the_no_fsync_row_reaches_no_disk_and_the_fsync_row_does(tmp_path: Path, monkeypatch) -> None:
    store = bench("bench_store")
    disk: list[int] = []
    monkeypatch.setattr(os, "fsync", disk.append)  # the real syncs, as the run file would reach them
    monkeypatch.setattr(os, "fdatasync", disk.append)
    records = store.make_records(3, 40)
    _, made = store.run_store(str(tmp_path / "sync.h5"), records, True)
    assert made == len(disk) >= len(records)  # every commit syncs (its journal record) at least once
    disk.clear()
    _, skipped = store.run_store(str(tmp_path / "nosync.h5"), records, False)
    assert disk == [] and skipped >= len(records)  # the same calls, none of them reaching the disk
    for name in ("sync.h5", "nosync.h5"):  # and both wrote the same trials and frames
        with RunFile.open(tmp_path / name) as run:
            assert run.records.ids() == [0, 1, 2]
            np.testing.assert_array_equal(run.records.read(2)["raw"]["load"].counts, records[2]["raw"]["load"].counts)


def test_the_store_rows_frames_and_trials_are_the_options(tmp_path: Path) -> None:
    store = bench("bench_store")
    t = store.measure(str(tmp_path), store.make_records(2, 30), repeat=1)
    assert t["fsyncs_sync"] >= 2 and t["fsyncs_nosync"] == 0
    with RunFile.open(tmp_path / "sync.h5") as run:
        assert run.records.ids() == [0, 1] and run.records.read(1)["raw"]["baseline"].counts.shape == (30, 6)
    with h5py.File(tmp_path / "plain.h5") as f:
        assert f["counts"].shape == (2 * 2 * 30, 6)
    with h5py.File(tmp_path / "durable.h5") as f:  # the baseline holds the same frames, filtered as the run file
        assert f["counts"].shape == (2 * 2 * 30, 6) and f["counts"].fletcher32 and f["counts"].compression == "gzip"
        assert f["counts"].chunks == (64, 6)
    with h5py.File(tmp_path / "sync.h5") as f:  # ... and the run file the same chunk length as the baseline
        assert f["entry/raw/time"].chunks == (store.chunk_of(30),)
    assert t["durable"] > 0


def test_processes_runs_that_many_fresh_processes_and_takes_medians(tmp_path: Path) -> None:
    out = tmp_path / "figures.json"
    script = HERE / "bench_store.py"
    args = ["--trials", "2", "--samples", "30", "--repeat", "1", "--processes", "3", "--figures", str(out)]
    printed = subprocess.run([sys.executable, str(script), *args], capture_output=True, text=True, check=True).stdout
    figures = json.loads(out.read_text())
    assert figures["processes"] == 3 and printed.count("bare h5py, same filters") == 3
    each = re.search(r"by frames/window: 30: \[([^\]]*)\]", printed)
    assert each is not None
    ratios = [float(x) for x in each.group(1).split(",")]
    assert len(ratios) == 3 and figures["30 frames fsync over durable h5py"] == pytest.approx(
        sorted(ratios)[1], abs=1e-3
    )


def test_the_durable_baseline_syncs_once_per_trial(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    store = bench("bench_store")
    disk: list[int] = []
    monkeypatch.setattr(os, "fsync", disk.append)
    store.run_durable(str(tmp_path / "d.h5"), store.make_records(5, 20), store.chunk_of(20))
    assert len(disk) == 5


def test_the_durable_baseline_without_fsync_syncs_nothing_and_writes_the_same(tmp_path: Path) -> None:
    store = bench("bench_store")
    t = store.measure(str(tmp_path), store.make_records(2, 30), repeat=1)
    assert t["durable_nosync"] > 0
    with h5py.File(tmp_path / "durable.h5") as a, h5py.File(tmp_path / "durable-nosync.h5") as b:
        np.testing.assert_array_equal(a["counts"][:], b["counts"][:])
    disk: list[int] = []
    real = os.fsync
    try:
        os.fsync = disk.append  # type: ignore[assignment]
        with store.fsyncs(False) as calls:
            store.run_durable(str(tmp_path / "d.h5"), store.make_records(3, 20), store.chunk_of(20))
    finally:
        os.fsync = real
    assert disk == [] and calls == [3]  # counted, none reaching the disk


# --------------------------------------------------------------------------- bench_tables


@pytest.mark.parametrize("split, every", [("contiguous", None), ("interleaved", 6)])
def test_the_split_option_gives_the_split_it_names(tmp_path: Path, split: str, every: int | None) -> None:
    tables = bench("bench_tables")
    tables.write_table(600, tmp_path / "t.csv", split)
    s = pd.read_csv(tmp_path / "t.csv")["set"].to_numpy()
    held = np.flatnonzero(s == "validation")
    if every:
        np.testing.assert_array_equal(held, np.arange(every - 1, 600, every))
    else:
        np.testing.assert_array_equal(held, np.arange(480, 600))


def test_each_step_runs_its_own_command_beside_its_own_baseline(tmp_path: Path) -> None:
    tables = bench("bench_tables")
    csv = tmp_path / "t.csv"
    seen = {step: tables.commands(step, csv, tmp_path) for step in tables.STEPS}
    assert [mine[2] for mine, _ in seen.values()] == ["fit", "validate", "import"]
    assert seen["fit"][1][1] == "fit" and seen["validate"][1][1] == "validate"
    assert Path(seen["import"][1][0]).name == "import_h5py.py"
    for _, base in seen.values():  # independent of labcli: none of its code in the baseline
        assert not re.search(r"^\s*(import|from)\s+labcli", Path(base[0]).read_text(), re.M)


@pytest.fixture(scope="module")
def trial_csv(tmp_path_factory) -> Path:
    table = paper_trials(400, seed=4, noise=True)
    table["trial"] = np.arange(len(table))
    table["set"] = np.where(np.arange(len(table)) % 6 == 5, "validation", "fit")
    path = tmp_path_factory.mktemp("tables") / "t.csv"
    table.to_csv(path, index=False)
    return path


def test_the_fit_baseline_is_the_four_regressions_labcli_fits(trial_csv: Path) -> None:
    got = json.loads(baseline("paper_lstsq.py", "fit", trial_csv, RIG["h2_m"], RIG["h3_m"]))
    # Eqs. 34-37 as printed: the labels as read (labcli's default also fits the potentiometers' play).
    model = TakumaModel(geometry=RIG, label_play="none").fit(pd.read_csv(trial_csv))
    for eq, names in TERMS.items():
        np.testing.assert_allclose(got[eq], [model.coefficients[k] for k in names], rtol=1e-9)


def test_the_validate_baseline_measures_what_labcli_measures(trial_csv: Path) -> None:
    got = json.loads(baseline("paper_lstsq.py", "validate", trial_csv, RIG["h2_m"], RIG["h3_m"]))
    table = pd.read_csv(trial_csv)
    ev = evaluate(TakumaModel(geometry=RIG, label_play="none").fit(table), table)
    assert all(m["n_flagged"] == 0 for m in ev["metrics"].values())  # no trial left out: the same trials
    for q, col in (("theta1", "theta1_deg"), ("theta2", "theta2_deg"), ("Fx", "Fx_N"), ("Fy", "Fy_N")):
        for measure in ("rmse", "mae", "max_abs", "bias", "r2"):
            assert got[col][measure] == pytest.approx(ev["metrics"][q][measure], rel=1e-7, abs=1e-12)


def test_the_import_baseline_writes_every_column(tmp_path: Path, trial_csv: Path) -> None:
    baseline("import_h5py.py", trial_csv, tmp_path / "t.h5")
    table = pd.read_csv(trial_csv)
    with h5py.File(tmp_path / "t.h5") as f:
        assert set(f) == set(table.columns) and f["Fx_N"].compression == "gzip"
        np.testing.assert_array_equal(f["Fx_N"][:], table["Fx_N"].to_numpy())
        assert f["set"][5] == b"validation"


# --------------------------------------------------------------------------- bench_classify_report


def test_the_classify_baseline_evaluates_the_same_force_model(tmp_path: Path) -> None:
    model = TakumaModel(geometry=RIG).fit(paper_trials(300, seed=2, theta2_deg=(5.0, 20.0)))
    model.save(tmp_path / "m.json")
    rng = np.random.default_rng(1)
    n = 40
    base = rng.uniform(0.28, 0.32, (n, 4))
    loaded = base * rng.uniform(0.97, 1.03, (n, 4))
    table = pd.DataFrame(
        np.column_stack([base, loaded]), columns=["P_L10", "P_R10", "P_L20", "P_R20", "P_L1", "P_R1", "P_L2", "P_R2"]
    )
    table.insert(0, "push", np.arange(1, n + 1))
    table.insert(1, "object", [f"o{i % 4}" for i in range(n)])
    table["R_m"], table["d_m"], table["phi_deg"] = 0.033, 0.01, 0.0
    table.to_csv(tmp_path / "p.csv", index=False)
    bands = json.dumps({"soft": [0, 1000], "hard": [1000, None]})
    out = json.loads(
        baseline("classify_groupby.py", tmp_path / "p.csv", tmp_path / "m.json", RIG["h2_m"], RIG["h3_m"], bands)
    )
    pred = model.predict(base, loaded)
    ok = np.asarray(pred["ok"]["Fx"]) & np.asarray(pred["ok"]["Fy"])  # where labcli gives the model's own value
    got = pd.DataFrame(out["pushes"])
    np.testing.assert_allclose(got["Fx_N"][ok], pred["Fx_N"][ok], rtol=1e-8)
    np.testing.assert_allclose(got["Fy_N"][ok], pred["Fy_N"][ok], rtol=1e-8)
    assert [o["object"] for o in out["objects"]] == ["o0", "o1", "o2", "o3"] and all(
        o["n"] == 10 for o in out["objects"]
    )


# --------------------------------------------------------------------------- fresh.py


def test_fresh_processes_are_measured_themselves_not_the_parent(tmp_path: Path) -> None:
    fresh = bench("fresh")
    spin = tmp_path / "spin.py"
    spin.write_text("import time\nt = time.process_time()\nwhile time.process_time() - t < 0.3: pass\n")
    hold = tmp_path / "hold.py"
    hold.write_text("b = bytearray(300 * 2**20)\nb[::4096] = b'x' * len(b[::4096])\n")
    idle = tmp_path / "idle.py"
    idle.write_text("pass\n")
    ballast = bytearray(400 * 2**20)  # the parent's own peak must not show in a child's
    ballast[::4096] = b"x" * len(ballast[::4096])
    runs = {p.stem: fresh.fresh([str(p)]) for p in (spin, hold, idle)}
    assert runs["spin"].cpu_s >= 0.3 > runs["idle"].cpu_s
    assert runs["hold"].peak_mib >= 300 > runs["idle"].peak_mib + 250
    assert runs["idle"].peak_mib < 100
    pair = fresh.interleaved("t", 3, [str(idle)], [str(spin)])
    assert len(pair.mine) == len(pair.base) == 3 and pair.ratio("cpu_s") < 0.5
    assert set(pair.figures()) >= {"t cpu ratio", "t labcli peak memory MiB", "t baseline wall s"}
    del ballast


def test_table_filters_measures_the_filters_the_run_file_uses():
    from labcli.core.paper import Column
    from labcli.core.store.columns import FILTERS, table_filters

    tf = bench("table_filters")
    assert tf.WAYS["gzip 4 shuffle"] == FILTERS  # the tables' filters before, the raw windows' still
    assert {**tf.WAYS["gzip 1"], "shuffle": False} == table_filters(Column("P", "MPa"))  # a float column's now
    assert table_filters(Column("trial", "1", kind="int"))["shuffle"] is True
    cols = {"x": (np.random.default_rng(1).normal(size=(5000, 2)).round(4), (1024, 2))}
    sizes = {way: tf.write(cols, ("x",), filters)[1] for way, filters in tf.WAYS.items()}
    assert sizes["gzip 1"] < sizes["gzip 1 shuffle"]  # decimal numbers: shuffling splits their repeats


# --------------------------------------------------------------------------- label_play_forces


def test_label_play_forces_reads_the_rigs_own_deflections_beside_the_pots():
    lp = bench("label_play_forces")
    # No effect at all: settled, the pots read the joints (their noise only), trial by trial.
    _, table, d_true, rest = lp.trials_with_truth("takuma2014", 1, 8.0, effects="ideal")
    assert d_true.shape == (len(table), 2) and rest.shape == (len(table), 2)
    assert np.max(np.abs(table[["theta1_deg", "theta2_deg"]].to_numpy() - d_true)) < 0.03
    # The play alone (0.2 deg full width): readings short of the joint's deflection, never by more than it.
    _, table, d_true, _ = lp.trials_with_truth("takuma2014", 1, 8.0, effects="backlash")
    read = table[["theta1_deg", "theta2_deg"]].to_numpy()
    moved = np.abs(d_true) > 0.5
    assert np.mean(np.abs(read[moved])) < np.mean(np.abs(d_true[moved])) - 0.05
    assert np.max(np.abs(read - d_true)) < 0.2 + 0.03


def test_label_play_forces_turns_on_only_the_effects_asked():
    lp = bench("label_play_forces")
    scales = lp._rig_kw("backlash,leak")["nonideal"].as_dict()
    assert scales["backlash"] == scales["leak"] == 1.0
    assert all(v == 0.0 for k, v in scales.items() if k not in ("backlash", "leak"))
    assert lp._rig_kw("") == {}
    with pytest.raises(SystemExit, match="Unknown effect.*frction"):
        lp._rig_kw("frction")


def test_study_trials_and_pushes_wait_and_resupply_as_the_protocol_does(monkeypatch):
    """The objects of study.py / sensitivity.py are pushed as `labcli acquire` would: every window
    after the protocols' earliest equilibrium (15 s, not drive.py's 6 s, whose thermal tail put
    the steel can at 1.8 times its stiffness), the chambers supplied again past the drift limit,
    and the pushes on the rig opened anew; a retaken baseline keeps the rest columns aligned."""
    ca = bench("classify_accuracy")
    from labcli.papers.takuma2014.sim.nonideal import NonIdeal

    seen: list[dict] = []
    rigs: list[object] = []

    def spy(real):
        def call(rig, *args, **kwargs):
            seen.append(kwargs)
            rigs.append(rig._rig)
            supplies = [0]
            supply = rig._rig.supply_air

            def counted():
                supplies[0] += 1
                supply()

            rig._rig.supply_air = counted
            out = real(rig, *args, **kwargs)
            kwargs["supplies"] = supplies[0]
            return out

        return call

    monkeypatch.setattr(ca, "simulate_weight_trials", spy(ca.simulate_weight_trials))
    monkeypatch.setattr(ca, "simulate_pushes", spy(ca.simulate_pushes))
    trials, table = ca.trials_and_pushes(2, 1, rig_kw={"nonideal": NonIdeal(realism="kind", leak=3.0)})
    assert [k["settle_s"] for k in seen] == [15.0, 15.0]
    assert [k["repressurise_kPa"] for k in seen] == [3.1, 3.1]
    assert seen[0]["supplies"] > 1  # the leak of three times the default made the run supply again
    assert rigs[0] is not rigs[1]
    assert len(trials) == 108 and len(table) == len(ca.DEMO_OBJECTS)
    for df in (trials, table):
        assert np.isfinite(df[["theta1_0_deg", "theta2_0_deg"]].to_numpy()).all()
    # The rest columns are each row's own baseline: the deflection label is the loaded reading minus it,
    # so the rest posture moves with the arm, not with a window left over from a drifted baseline.
    assert np.ptp(trials["theta1_0_deg"]) < 1.0


def _logged_trials(monkeypatch, **kwargs) -> tuple[list[tuple], pd.DataFrame]:
    """sensing_accuracy.trials on the straight protocol, with every wait, window (calibrated
    channel means), supply and load the drive makes, in order."""
    sa, acquired = bench("sensing_accuracy"), bench("acquired")
    calibration = load_protocol("takuma2014").calibration
    events: list[tuple] = []

    class Logged(acquired.Windows):
        def advance(self, seconds):
            events.append(("wait", seconds))
            self._rig.advance(seconds)

        def samples(self, n, rate_hz):
            out = super().samples(n, rate_hz)
            events.append(("window", np.asarray(calibration.to_si(out[1]), dtype=float).mean(axis=0)))
            return out

        def supply_air(self):
            events.append(("supply",))
            super().supply_air()

        def hang_weight(self, *args):
            events.append(("load",))
            self._rig.hang_weight(*args)

    monkeypatch.setattr(sa, "_Recorder", Logged)
    _, table = sa.trials("takuma2014", 2, **kwargs)
    return events, table


def test_sensing_trials_wait_and_resupply_as_the_protocol_does(monkeypatch):
    """The sensing benchmarks' trials (sensing_accuracy.trials, under study.py, sensitivity.py,
    baseline_estimator.py, friction_estimator.py, phi_bent.py) are taken as `labcli acquire`
    takes them: every window after the protocol's earliest equilibrium, and the chambers supplied
    again when a baseline has drifted past acquisition.repressurise_kPa since the last supply, and
    not before; a retaken baseline replaces the drifted one in the rest columns."""
    from labcli.papers.takuma2014.sim.nonideal import NonIdeal

    proto = load_protocol("takuma2014")
    settle = 3 * proto.settling.window_s + proto.settling.hold_s  # the settling rule's earliest acceptance
    limit = proto.air.repressurise_kPa
    events, table = _logged_trials(monkeypatch, rig_kw={"nonideal": NonIdeal(realism="kind", leak=3.0)})
    windows = [i for i, e in enumerate(events) if e[0] == "window"]
    assert len(windows) >= 2 * len(table) == 216
    assert all(events[i - 1] == ("wait", settle) for i in windows)
    from labcli.papers.takuma2014.sim.rig import SimRig

    channels = list(SimRig(seed=2).channels)
    p_idx = [channels.index(c) for c in ("P_L1", "P_R1", "P_L2", "P_R2")]
    pots = [channels.index(c) for c in ("POT1", "POT2")]
    reference, accepted, drifted, carried = None, [], 0, 0.0
    for i in windows:
        after = events[i + 1][0] if i + 1 < len(events) else "end"
        if after not in ("load", "supply"):
            continue  # a loaded window
        p = events[i][1][p_idx]
        if reference is None:
            reference = p  # the first baseline since the last supply
            assert after == "load"
        else:
            drift = float(np.max(np.abs(p - reference))) * 1e3
            if after == "supply":
                assert drift > limit
                drifted, reference = drifted + 1, None
            else:
                assert drift <= limit
                carried = max(carried, drift)
        if after == "load":
            accepted.append(events[i][1][pots])
    assert drifted >= 1  # the tripled leak made the run supply again
    assert carried > limit / 2  # and it held the chambers while the drift stayed under the limit
    np.testing.assert_allclose(table[["theta1_0_deg", "theta2_0_deg"]], np.degrees(accepted))


def test_sensing_trials_settle_option_takes_them_the_old_way(monkeypatch):
    """``--settle 8 --repressurise 0``: every window 8 s after the change, the valves held for the run."""
    events, table = _logged_trials(monkeypatch, settle_s=8.0, repressurise_kPa=0.0)
    windows = [i for i, e in enumerate(events) if e[0] == "window"]
    assert len(windows) == 2 * len(table)
    assert all(events[i - 1] == ("wait", 8.0) for i in windows)
    assert [e for e in events if e[0] == "supply"] == [("supply",)]  # the first supply only


def test_sensing_trials_mark_the_baselines_taken_after_a_resupply():
    """sensing_accuracy.trials' ``supplies``: a row is marked when the chambers were supplied just
    before its baseline.  A supply brings air back and the closed chambers only lose it, so every
    marked baseline lies above the one before it and every other one below; a rig without the leak
    never drifts, and only the run's first baseline (after its first supply) is marked."""
    from labcli.papers.takuma2014.sim.nonideal import NonIdeal

    sa = bench("sensing_accuracy")
    marks: list = []
    _, table = sa.trials("takuma2014", 2, rig_kw={"nonideal": NonIdeal(realism="kind", leak=3.0)}, supplies=marks)
    marked = np.asarray(marks, dtype=bool)
    assert len(marked) == len(table) and marked[0] and 10 < marked.sum() < len(table)
    change = np.diff(table[["P_L10", "P_R10", "P_L20", "P_R20"]].to_numpy(dtype=float), axis=0).mean(axis=1)
    assert (change[marked[1:]] > 0).all() and (change[~marked[1:]] < 0).all()
    marks.clear()
    sa.trials("takuma2014", 2, without="leak", supplies=marks)
    assert marks[0] and not any(marks[1:])


def test_sensing_validation_moves_to_the_rows_asked_and_keeps_its_size():
    """sensing_accuracy.move_validation: the plan's 18 validation trials (its last rows) become fit
    trials and the 18 rows from the one asked become the validation set; the table is otherwise the
    same, and a row that leaves fewer than 18 after it is refused in a sentence."""
    sa = bench("sensing_accuracy")
    table = pd.concat(
        [paper_trials(90, seed=3), paper_trials(18, seed=4, set_name="validation", start_id=91)], ignore_index=True
    )
    moved = sa.move_validation(table, 45)
    before, after = (t["set"].to_numpy() == "validation" for t in (table, moved))
    assert after.sum() == before.sum() == 18
    assert np.flatnonzero(after).tolist() == list(range(45, 63))
    assert not (before & after).any() and (moved["set"] != "validation").sum() == len(table) - 18
    pd.testing.assert_frame_equal(moved.drop(columns="set"), table.drop(columns="set"))
    assert sa.move_validation(table, len(table) - 18)["set"].iloc[-18:].eq("validation").all()
    for bad in (-1, len(table) - 17):
        with pytest.raises(ValueError, match="takes a row from 0 to"):
            sa.move_validation(table, bad)


def test_sensing_rig_effects_one_off_or_alone():
    """sensing_accuracy.nonideal_of: ``without`` turns one effect off and keeps the realism's
    others at their levels; ``ideal`` with a name keeps that one alone; the kind rig is the default."""
    from labcli.papers.takuma2014.sim.nonideal import NonIdeal

    sa = bench("sensing_accuracy")
    assert sa.nonideal_of() == NonIdeal(realism="kind")  # explicit: the simulator's default is the literature's
    lit = NonIdeal(realism="literature").as_dict()
    off = sa.nonideal_of(without="thermal", realism="literature")
    assert off.realism == "literature" and off.thermal == 0.0
    assert {k: v for k, v in off.as_dict().items() if k != "thermal"} == {
        k: v for k, v in lit.items() if k != "thermal"
    }
    alone = sa.nonideal_of("friction").as_dict()
    assert alone["friction"] == 1.0 and sum(alone.values()) == 1.0
    assert sum(sa.nonideal_of(True, realism="literature").as_dict().values()) == 0.0


def test_phi_bent_direction_error_is_the_turn_from_the_radial_force():
    """phi_bent.direction_error: a force turned by a known angle from the radial one (the object's
    true centre, Eq. 39 from the rest contact point, to the loaded contact point) reads that angle."""
    from labcli.papers.takuma2014.models.geometry import contact_point
    from labcli.papers.takuma2014.models.stiffness import object_centre

    pb = bench("phi_bent")
    rig = dict(load_protocol("takuma2014-bent").settings.rig)
    h2, h3 = rig["h2_m"], rig["h3_m"]
    pushes = pd.DataFrame(
        {
            "theta1_0_deg": [-0.8, 0.3, 0.0],
            "theta2_0_deg": [19.2, 20.1, 18.0],
            "theta1_deg": [0.7, 0.3, 1.1],
            "theta2_deg": [1.3, 0.8, -0.4],
            "true_phi_deg": [0.0, 15.0, -30.0],
            "R_m": [0.033, 0.033, 0.0325],
            "d_m": [0.01, 0.01, 0.008],
        }
    )
    rest = np.radians(pushes[["theta1_0_deg", "theta2_0_deg"]].to_numpy())
    moved = rest + np.radians(pushes[["theta1_deg", "theta2_deg"]].to_numpy())
    C0, C = contact_point(rest[:, 0], rest[:, 1], h2, h3), contact_point(moved[:, 0], moved[:, 1], h2, h3)
    O2 = object_centre(
        pushes["R_m"].to_numpy(), pushes["d_m"].to_numpy(), np.radians(pushes["true_phi_deg"]), h2, h3, C0
    )
    radial = np.arctan2(*(C - O2)[:, ::-1].T)
    for turn in (0.0, 10.0, -25.0, 170.0):
        a = radial + np.radians(turn)
        ps = pd.DataFrame({"Fx_N": 3.0 * np.cos(a), "Fy_N": 3.0 * np.sin(a)})
        np.testing.assert_allclose(pb.direction_error(pushes, ps, rig), turn, atol=1e-9)


def test_phi_bent_passes_its_realism_effects_and_timing(monkeypatch, capsys):
    """phi_bent.py gives the rig its realism even when it is the kind one (the rig's own default may
    change), scales an effect by --effect, and times trials and pushes by --settle/--repressurise."""
    pb = bench("phi_bent")
    seen = []

    def fake_run(seed, angles, rig_kw=None):
        seen.append((seed, rig_kw["nonideal"], dict(pb.AIR)))
        pb.BIAS.append((1.0, 0.5))
        pb.CONFIDENT_WRONG.append(0)
        return 50, 60, 6

    monkeypatch.setattr(pb, "run", fake_run)
    monkeypatch.setattr(pb, "AIR", {})
    monkeypatch.setattr(pb, "BIAS", [])
    monkeypatch.setattr(pb, "CONFIDENT_WRONG", [])
    argv = ["phi_bent.py", "--seeds", "4-5", "--effect", "repeat=0", "--settle", "8", "--repressurise", "0"]
    monkeypatch.setattr(sys, "argv", argv)
    pb.main()
    assert [s for s, _, _ in seen] == [4, 5]
    scales = seen[0][1]
    assert scales.realism == "kind" and scales.repeat == 0.0 and scales.friction == 1.0
    assert seen[0][2] == {"settle_s": 8.0, "repressurise_kPa": 0.0}
    monkeypatch.setattr(sys, "argv", ["phi_bent.py", "--seeds", "1-1", "--realism", "literature"])
    monkeypatch.setattr(pb, "AIR", {})
    pb.main()
    assert seen[-1][1].realism == "literature" and seen[-1][1].repeat == 1.0 and seen[-1][2] == {}
    assert "+0.5 deg on average" in capsys.readouterr().out


# --------------------------------------------------------------------------- interval_coverage


def test_interval_coverage_diagnoses_with_the_held_out_errors_the_fit_chose_its_routes_by():
    """The fit trials' held-out errors it prints are the route choice's own: over the trials both
    forms report, their RMSE is the stacked RMSE the fit recorded, whichever route each quantity took."""
    ic = bench("interval_coverage")
    from labcli.papers.takuma2014.models.posture import PostureModel, limits_from_protocol

    proto, table = ic.sa.trials("takuma2014", 1, realism="kind")
    model = PostureModel(geometry=proto.settings.rig, limits=limits_from_protocol(proto), friction=True)
    with ic.held_out_capture() as seen:
        model.fit(table)
    assert len(seen["rows"]) == int((table["set"] == "fit").sum())
    for q in ic.QUANTITIES:
        stats = model.fit_stats["routes_cv"][q]
        if not stats["n_both"]:
            continue
        cv = seen["cv"]
        both = cv["posture_ok"][q] & cv["paper_ok"][q] & np.isfinite(cv["paper"][q]) & np.isfinite(cv["posture"][q])
        scale = np.degrees(1.0) if q.startswith("theta") else 1.0
        assert ic.rms(ic.route_errors(model, seen, q)[both]) == pytest.approx(scale * stats["rmse_stacked"], rel=1e-9)


def test_interval_coverage_counts_an_error_inside_its_interval_and_resamples_seeds():
    ic = bench("interval_coverage")
    rng = np.random.default_rng(0)
    # Seed A: 3 of 4 inside (1.96 standard errors is inside, 2 is not); seed B: 1 of 1.
    a = {"Fx": {"err": np.array([0.0, 1.0, -1.959, 2.0]), "se": np.ones(4)}}
    b = {"Fx": {"err": np.array([0.5]), "se": np.ones(1)}}
    p, lo, hi = ic.coverage_ci([a, b], "Fx", rng)
    assert p == pytest.approx(4 / 5)
    assert 0.75 <= lo <= p <= hi <= 1.0  # a resample holds seed A alone (3/4) at worst, B alone (1) at best
    same, slo, shi = ic.coverage_ci([a, a, a], "Fx", rng)
    assert same == slo == shi == pytest.approx(0.75)  # identical seeds: nothing to resample


# --------------------------------------------------------------------------- rig_options: --realism and --seeds

RIG_CODE = re.compile(
    r"SimRig|sim://|NonIdeal|make_rig|simulated_port|trials_and_pushes|run_session|study\.|long_capture"
)


def test_seeds_read_as_ranges_lists_and_both() -> None:
    ro = bench("rig_options")
    assert ro.seeds_of("11-30") == list(range(11, 31))
    assert ro.seeds_of("1,4,7") == [1, 4, 7] and ro.seeds_of("3") == [3]
    assert ro.seeds_of("1-3,7") == [1, 2, 3, 7] and ro.seeds_of(" 2 - 4 ") == [2, 3, 4]
    for seeds in ([11, 12, 13, 14], [1, 4, 7], [1, 2, 3, 7, 9, 10], [5]):
        assert ro.seeds_of(ro.seeds_text(seeds)) == seeds  # what a benchmark prints reads back
    assert ro.seeds_text(list(range(11, 31))) == "11-30"


@pytest.mark.parametrize("bad", ["", "2-x", "3-1", "0", "0-4", "1,,2", "-3", "1-2-3", "1.5", "1,1", "1-3,2"])
def test_bad_seeds_are_one_sentence(bad: str) -> None:
    ro = bench("rig_options")
    with pytest.raises(ValueError) as e:
        ro.seeds_of(bad)
    text = str(e.value)
    assert text.startswith("--seeds ") and "\n" not in text and repr(bad) in text


def test_the_realism_takes_the_simulators_names_one_or_several() -> None:
    from labcli.papers.takuma2014.sim.nonideal import REALISMS

    ro = bench("rig_options")
    assert set(REALISMS) == {"kind", "literature"}
    assert ro.realism_of("kind") == "kind" and ro.realisms_of("literature,kind") == ["literature", "kind"]
    for bad in ("harsh", "kind,kind", "kind,", ""):
        with pytest.raises(ValueError, match="^--realism takes"):
            ro.realisms_of(bad)
    with pytest.raises(ValueError, match="^--realism takes"):
        ro.realism_of("kind,literature")


def test_the_parser_reads_the_options_and_refuses_in_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    ro = bench("rig_options")

    def parser(**kw: object):
        ap = ro.bench_parser("A benchmark.\n\nMore.", prog="bench.py")
        ro.add_rig_options(ap, **kw)
        return ap

    args = parser(realism="kind", seeds="1-10").parse_args([])
    assert args.realism == "kind" and args.seeds == list(range(1, 11))  # the defaults, read as given ones are
    args = parser(realism="kind", seeds="1-10").parse_args(["--realism", "literature", "--seeds", "11-12,15"])
    assert args.realism == "literature" and args.seeds == [11, 12, 15]
    assert parser(realism="literature,kind", seeds="3", several=True).parse_args([]).realism == ["literature", "kind"]
    for kw, argv, said in (
        ({"realism": "kind", "seeds": "1"}, ["--seeds", "5-2"], "argument --seeds: takes a range"),
        ({"realism": "kind", "seeds": "1"}, ["--realism", "kind,literature"], "argument --realism: takes"),
        ({"realism": "kind", "seeds": "1", "one": True}, ["--seeds", "1-3"], "takes one seed here"),
        ({"realism": "kind", "seeds": "1"}, ["--sede", "3"], "unrecognized arguments: --sede"),
    ):
        with pytest.raises(SystemExit) as e:
            parser(**kw).parse_args(argv)
        err = capsys.readouterr().err
        assert e.value.code == 2 and err.count("\n") == 1 and err.startswith("bench.py: ") and said in err
        assert "usage" not in err and err.endswith(".\n")
    with pytest.raises(ValueError):  # a benchmark whose own default is wrong fails at once, not in a run
        parser(realism="harsh", seeds="1")


def test_every_benchmark_of_the_rig_takes_the_shared_options() -> None:
    """A benchmark that runs the simulated McKibben rig takes --realism and --seeds from rig_options.py
    (with a default realism of its own, never the simulator's, which has moved once), and none parses
    them its own way; the rPAM benchmarks take --seeds alone."""
    own_way = re.compile(r"add_argument\(\s*\"--(seeds|seed|realism)\"|def (seeds_of|parse_seeds|seeds_from|_seeds)\(")
    rig, checked = re.compile(r"add_rig_options\(\w+, realism=\"[a-z,]+\""), []
    for path in sorted(HERE.glob("*.py")):
        text = path.read_text(encoding="utf-8")
        # kill_layouts.py's --seed draws its kills (its rig is a stand-in); run_all.py runs the others.
        if path.name in ("rig_options.py", "test_bench_options.py", "kill_layouts.py", "run_all.py"):
            continue
        if "parse_args(" not in text:
            continue
        assert not own_way.search(text), f"{path.name} parses --seeds or --realism its own way"
        if path.name.startswith("rpam_"):
            assert "add_seeds_option(" in text, path.name
        elif RIG_CODE.search(text):
            assert rig.search(text), f"{path.name} runs the rig without add_rig_options(ap, realism=...)"
            checked.append(path.name)
    assert {"bench_sim.py", "bench_models.py", "bench_classify_report.py", "bench_firmware_model.py"} <= set(checked)
    assert len(checked) >= 25


@pytest.mark.parametrize("script", ["bench_sim.py", "guard_mistakes.py"])
def test_a_benchmark_refuses_bad_seeds_in_one_sentence(script: str) -> None:
    out = subprocess.run(
        [sys.executable, str(HERE / script), "--seeds", "11-x"], capture_output=True, text=True, timeout=120
    )
    assert out.returncode == 2 and out.stdout == ""
    assert out.stderr.count("\n") == 1 and "Traceback" not in out.stderr and "'11-x'" in out.stderr


# --------------------------------------------------------------------------- --relief (guard_mistakes, bench_guard)


@pytest.mark.parametrize("side, vented", [("L", ("P_L1", "P_L2")), ("R", ("P_R1", "P_R2")), ("load", ("P_R1", "P_R2"))])
def test_the_relief_option_gives_the_shipped_protocol_the_relief_of_several_captures(side, vented) -> None:
    from labcli.core.air import CAPTURE_RELIEF
    from labcli.core.protocol import loads_protocol

    rig_options = bench("rig_options")
    shipped = load_protocol("takuma2014")
    assert shipped.air.friction_relief_s == 0  # off by default with one capture a load
    air = loads_protocol(rig_options.relieved(shipped.text, side)).air
    assert (air.friction_relief_s, air.friction_relief_vent_s) == CAPTURE_RELIEF
    assert air.relief_vented(["P_L1", "P_R1", "P_L2", "P_R2"], "R") == vented  # "load": the side pulled towards
    assert air.captures_per_load == 1
    with pytest.raises(ValueError, match="one \\[acquisition\\] table"):
        rig_options.relieved(shipped.text.replace("[acquisition]\n", "[acq]\n"), side)
    ap = rig_options.bench_parser("x")
    rig_options.add_relief_option(ap)
    assert ap.parse_args([]).relief is None and ap.parse_args(["--relief"]).relief == "load"
    assert ap.parse_args(["--relief", "R"]).relief == "R"
