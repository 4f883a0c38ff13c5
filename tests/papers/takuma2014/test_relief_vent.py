"""Which side the friction relief vents is the run's stored choice: a new run writes the per-load
default into the protocol it stores, a run begun before that default (no key) keeps venting L when
resumed, and "load" without the rig's geometry is refused before anything is stored."""

from __future__ import annotations

import io
import os
import re
import shutil
import signal
from dataclasses import replace
from pathlib import Path

import h5py
import pandas as pd
import pytest
from click.testing import CliRunner
from rich.console import Console

from labcli.cli import cli
from labcli.core.acquisition import acquire
from labcli.core.air import AirSettings
from labcli.core.paper import AcquireOptions
from labcli.core.protocol import load_protocol, loads_protocol, with_captures
from labcli.core.store import RunFile
from labcli.core.store.records import Records
from labcli.core.ui import UnattendedUI
from labcli.errors import StoreError
from labcli.papers.takuma2014 import acquisition as force_acquisition
from labcli.papers.takuma2014.guard_prior import PhysicsPrior
from labcli.papers.takuma2014.models.inputs import load_trial_source

ROOT = Path(__file__).resolve().parents[3]

PORT = "sim://?seed=21&clock=virtual"
# Loads at 0 deg pull the upright arm towards R (Fx > 0), at 180 deg towards L.
PLAN = "trial,set,mass_g,direction_deg\n1,fit,500,0\n2,fit,500,180\n3,validation,500,0\n"


def quiet() -> UnattendedUI:
    return UnattendedUI(console=Console(file=io.StringIO()))


@pytest.fixture
def vented(monkeypatch):
    """The side of every relief, in order ("L" or "R", from the channels vented)."""
    sides: list[str] = []
    real = AirSettings.relief_vented

    def spy(self, names, pulled=None):
        out = real(self, names, pulled)
        sides.append("".join(sorted({n[2] for n in out})))
        return out

    monkeypatch.setattr(AirSettings, "relief_vented", spy)
    return sides


def _plan(tmp_path):
    plan = tmp_path / "plan.csv"
    plan.write_text(PLAN)
    return plan


def _interrupted(run, mp, **kw):
    """``acquire(run, ...)`` of the plan at two captures a load, Ctrl-C pressed as record 3 (load 2's
    first capture) is written: the outcome."""
    real = Records.write

    def pressed(self, record):
        if record["trial"] == 3:
            os.kill(os.getpid(), signal.SIGINT)
        return real(self, record)

    mp.setattr(Records, "write", pressed)
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        return acquire(run, PORT, plan=_plan(run.parent), unattended=True, ui=quiet(), captures=2, **kw)
    finally:
        signal.signal(signal.SIGINT, previous)


def test_a_new_run_stores_the_per_load_default_and_vents_the_side_each_load_pulls(tmp_path, vented):
    run = tmp_path / "new.h5"
    out = acquire(run, PORT, plan=_plan(tmp_path), unattended=True, ui=quiet(), captures=2)
    assert out.exit_code == 0, out.message
    with RunFile.open(run) as f:
        stored = loads_protocol(f.protocol_text)
    assert re.search(r'^friction_relief_vent = "load"$', stored.text, flags=re.MULTILINE)
    assert stored.air.friction_relief_vent == "load" and stored.air.captures_per_load == 2
    assert vented == ["R", "R", "L", "L", "R", "R"]
    # Each record keeps the side vented before its baseline; a load's averaged row keeps its captures'.
    with RunFile.open(run) as f:
        assert list(f.records.table()["relief_vent"]) == vented
        assert f.records.read(3)["relief_vent"] == "L"
    assert list(load_trial_source(run).table["relief_vent"]) == ["R", "L", "R"]


def test_a_run_begun_before_the_per_load_default_keeps_venting_l_when_resumed(tmp_path, monkeypatch, vented):
    """An old-style run: its stored protocol has the relief (two captures a load) but no vent key, and
    it vented L before every capture.  Interrupted after load 1, resumed: it vents L again."""
    run = tmp_path / "old.h5"
    # The toolkit before the per-load default: the key left out of the stored protocol, L vented.
    with monkeypatch.context() as mp:
        mp.setattr(
            force_acquisition,
            "_relief_vent",
            lambda protocol, options: replace(protocol, air=replace(protocol.air, friction_relief_vent="L")),
        )
        first = _interrupted(run, mp)
    assert first.exit_code != 0 and vented == ["L", "L", "L"]
    with RunFile.open(run) as f:
        assert "friction_relief_vent" not in f.protocol_text and f.records.ids() == [1, 2, 3]
    vented.clear()
    resumed = acquire(run, PORT, resume=True, unattended=True, ui=quiet())
    assert resumed.exit_code == 0, resumed.message
    # Loads 2 and 3 pull L and R; per load it would vent L, R, R: the run's own choice vents L.
    assert vented == ["L", "L", "L"]
    with RunFile.open(run) as f:
        assert "friction_relief_vent" not in f.protocol_text and f.records.ids() == [1, 2, 3, 4, 5, 6]
        assert list(f.records.table()["relief_vent"]) == ["L"] * 6


def test_a_resumed_run_that_stored_its_side_vents_it(tmp_path, vented):
    """A side given in the protocol is stored as given and vented again when resumed."""
    proto = tmp_path / "r.toml"
    proto.write_text(
        load_protocol("takuma2014").text.replace("[acquisition]\n", '[acquisition]\nfriction_relief_vent = "R"\n')
    )
    run = tmp_path / "r.h5"
    with pytest.MonkeyPatch.context() as mp:
        assert _interrupted(run, mp, protocol=str(proto)).exit_code != 0
    assert vented == ["R", "R", "R"]
    vented.clear()
    assert acquire(run, PORT, resume=True, unattended=True, ui=quiet()).exit_code == 0
    assert vented == ["R", "R", "R"]


def _unnamed(tmp_path, extra: str = ""):
    """The shipped protocol with its angle channels named otherwise: the rig's statics cannot read
    them, so they find no side a load pulls towards (no PhysicsPrior; nor the paper's model)."""
    text = load_protocol("takuma2014").text.replace("POT1", "ANG1").replace("POT2", "ANG2")
    path = tmp_path / "unnamed.toml"
    path.write_text(text.replace("[acquisition]\n", "[acquisition]\n" + extra))
    assert PhysicsPrior.of(load_protocol(str(path))) is None
    return path


def test_venting_per_load_where_the_statics_find_no_side_is_refused_in_one_sentence(tmp_path):
    proto, run = _unnamed(tmp_path), tmp_path / "x.h5"
    args = ["acquire", str(run), "--port", PORT, "--unattended", "--protocol", str(proto), "--plan"]
    res = CliRunner().invoke(cli, [*args, str(_plan(tmp_path)), "--captures", "2"])
    assert res.exit_code == 1 and not run.exists()
    assert res.output == (
        "Error: The friction relief of takuma2014 vents the side each load pulls the arm towards "
        '(acquisition.friction_relief_vent = "load", the default), which the rig\'s statics find from its [rig] '
        "geometry and the channels P_L1, P_R1, P_L2, P_R2, POT1 and POT2, and the protocol does not name them "
        'all: name them so, or set friction_relief_vent = "L" or "R" to vent that side before every trial.\n'
    )


@pytest.mark.parametrize("extra", ['friction_relief_vent = "R"\n', ""])
def test_a_side_given_or_no_relief_needs_no_statics(tmp_path, extra):
    """A side given is vented whatever the channels; without the relief nothing is vented."""
    proto = with_captures(load_protocol(str(_unnamed(tmp_path, extra))), 2 if extra else 1)
    planned = force_acquisition._relief_vent(proto, AcquireOptions(str(tmp_path / "x.h5")))
    assert planned.air.friction_relief_vent == ("R" if extra else "load")
    assert planned.air.friction_relief_vent_s == (2.0 if extra else 0.0)
    assert planned.text.count("friction_relief_vent =") == (1 if extra else 0)


def test_a_resumed_run_whose_statics_find_no_side_keeps_venting_l():
    """A run begun with "load" where the statics found no side vented L (before it was refused): resumed, L."""
    text = load_protocol("takuma2014").text.replace("POT1", "ANG1").replace("POT2", "ANG2")
    stored = loads_protocol(text.replace("[acquisition]\n", '[acquisition]\nfriction_relief_vent = "load"\n'))
    stored = with_captures(stored, 2)
    resumed = force_acquisition._relief_vent(stored, AcquireOptions("x.h5", resume=object()))
    assert resumed.air.friction_relief_vent == "L" and resumed.text == stored.text


def test_a_run_without_the_relief_stores_no_side(tmp_path):
    run = tmp_path / "plain.h5"
    assert acquire(run, PORT, plan=_plan(tmp_path), unattended=True, ui=quiet()).exit_code == 0
    with RunFile.open(run) as f:
        assert "relief_vent" not in f.records.table().columns and "relief_vent" not in f.records.read(1)


def test_a_run_file_from_before_the_column_reads_and_takes_records_without_it(tmp_path):
    """tests/data/v3/force-before-marks.h5 was written before records kept the side vented (the sample
    runs, made again, keep it): it reads as before, and a record written to it (a resumed run) is
    stored without the side, nothing else changed."""
    path = tmp_path / "force.h5"
    shutil.copy(ROOT / "tests" / "data" / "v3" / "force-before-marks.h5", path)
    with h5py.File(path, "r") as f:
        assert "relief_vent" not in f["entry/trials"]
    with RunFile.open(path) as f:
        before, ids = f.records.table(), f.records.ids()
        rec = f.records.read(ids[-1])
    assert "relief_vent" not in before.columns and "relief_vent" not in rec
    with RunFile.open(path, "a") as f:
        f.records.write({**rec, "trial": max(ids) + 1, "relief_vent": "R"})
    with RunFile.open(path) as f:
        after = f.records.table()
        assert f.records.ids() == [*ids, max(ids) + 1] and after.iloc[: len(ids)].equals(before)
        assert "relief_vent" not in after.columns and f.verify()["ok"]


def test_the_side_goes_out_with_export_and_back_with_import(tmp_path):
    """Beside the exchange table's columns (docs/table-formats.md): exported, and imported back as the
    run's own column of that name, which the labels read."""
    run = tmp_path / "r.h5"
    assert acquire(run, PORT, plan=_plan(tmp_path), unattended=True, ui=quiet(), captures=2).exit_code == 0
    table = tmp_path / "r.csv"
    assert CliRunner().invoke(cli, ["export", str(run), "-o", str(table)]).exit_code == 0
    rows = pd.read_csv(table, keep_default_na=False)
    assert list(rows["relief_vent"]) == ["R", "R", "L", "L", "R", "R"]
    back = tmp_path / "back.h5"
    res = CliRunner().invoke(cli, ["import", str(table), "-o", str(back), "--protocol", "takuma2014"])
    assert res.exit_code == 0, res.output
    with RunFile.open(back) as f:
        assert list(f.records.table()["relief_vent"]) == list(rows["relief_vent"])


@pytest.mark.parametrize("side", ["left", "l", "1"])
def test_an_imported_table_with_another_side_is_refused_in_one_sentence(tmp_path, side):
    """The labels read a relieved rest from its side and take any other value as no relief: an
    imported table naming another side is refused, naming the trial, before any file is made."""
    run, table = tmp_path / "r.h5", tmp_path / "r.csv"
    assert acquire(run, PORT, plan=_plan(tmp_path), unattended=True, ui=quiet(), captures=2).exit_code == 0
    assert CliRunner().invoke(cli, ["export", str(run), "-o", str(table)]).exit_code == 0
    rows = pd.read_csv(table, keep_default_na=False)
    rows.loc[3, "relief_vent"] = side
    rows.to_csv(table, index=False)
    back = tmp_path / "back.h5"
    res = CliRunner().invoke(cli, ["import", str(table), "-o", str(back), "--protocol", "takuma2014"])
    assert res.exit_code == 1 and not back.exists()
    assert res.output == f"Error: trial {rows['trial'][3]}: relief_vent must be L, R or empty, got {side!r}.\n"


def test_a_record_with_another_side_is_refused_before_anything_is_written(tmp_path):
    run = tmp_path / "r.h5"
    assert acquire(run, PORT, plan=_plan(tmp_path), unattended=True, ui=quiet()).exit_code == 0
    with RunFile.open(run, "a") as f:
        rec = f.records.read(1)
        with pytest.raises(StoreError) as err:
            f.records.write({**rec, "trial": 9, "relief_vent": "left"})
        assert str(err.value) == "trial 9 record: relief_vent must be L, R or empty, got 'left'."
        assert f.records.ids() == [1, 2, 3]


def test_a_relief_given_as_dotted_keys_without_its_side_is_refused_in_one_sentence(tmp_path):
    """No [acquisition] header to write the per-load default under: the run could not store what it
    vents, so it is refused before anything is written, naming what to write by hand."""
    bare = load_protocol("takuma2014").text.replace("[acquisition]\n", "").replace("rate_hz = 200.0\n", "")
    dotted = (
        "acquisition.rate_hz = 200.0\nacquisition.friction_relief_s = 3.0\nacquisition.friction_relief_vent_s = 2.0\n"
    )
    proto, run = tmp_path / "dotted.toml", tmp_path / "x.h5"
    proto.write_text(dotted + bare)
    args = ["acquire", str(run), "--port", PORT, "--unattended", "--protocol", str(proto), "--plan"]
    res = CliRunner().invoke(cli, [*args, str(_plan(tmp_path))])
    assert res.exit_code == 1 and not run.exists()
    assert res.output == (
        "Error: takuma2014 gives its acquisition settings without an [acquisition] table header; write "
        'friction_relief_vent = "load" there (or "L", "R"), so that the run records the side it vents.\n'
    )
    proto.write_text(dotted + 'acquisition.friction_relief_vent = "R"\n' + bare)  # written by hand: taken
    out = acquire(run, PORT, plan=_plan(tmp_path), unattended=True, ui=quiet(), protocol=str(proto))
    assert out.exit_code == 0, out.message
    with RunFile.open(run) as f:
        assert list(f.records.table()["relief_vent"]) == ["R", "R", "R"]


@pytest.mark.parametrize("side", ["", 'friction_relief_vent = "L"\n'])
def test_a_push_protocol_venting_per_load_is_refused_and_a_side_given_is_kept(tmp_path, side):
    """A push has no load whose pull the statics could read, so "load" (the default) would vent L
    without saying so: refused in one sentence before anything is written; a side given is kept."""
    text = load_protocol("takuma2014-stiffness").text.replace(
        "[acquisition]\n", "[acquisition]\nfriction_relief_s = 3.0\nfriction_relief_vent_s = 2.0\n" + side
    )
    proto, run = tmp_path / "push.toml", tmp_path / "p.h5"
    proto.write_text(text)
    if side:
        planned = force_acquisition._relief_vent(load_protocol(str(proto)), AcquireOptions(str(run)))
        assert (planned.air.friction_relief_vent, planned.air.friction_relief_vent_s) == ("L", 2.0)
        return
    res = CliRunner().invoke(cli, ["acquire", str(run), "--port", PORT, "--unattended", "--protocol", str(proto)])
    assert res.exit_code == 1 and not run.exists()
    assert res.output == (
        "Error: The friction relief of takuma2014-stiffness vents the side each load pulls the arm towards "
        '(acquisition.friction_relief_vent = "load", the default), and a push has no load to take it from: '
        'set friction_relief_vent = "L" or "R" to vent that side before every push.\n'
    )
