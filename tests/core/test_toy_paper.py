"""A third paper, defined entirely in the tests, runs through the whole toolkit.

The toy paper (:mod:`support.toy`: a 1-DoF rig, one pressure and one angle, two
trials) is registered at run time; nothing in labcli names it.  ``labcli acquire
--unattended`` records it on its own simulated rig (``sim://?mode=toy``), ``labcli
export`` writes its table and ``labcli inspect`` describes the run, each through the
interfaces of :mod:`labcli.core.paper` only.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from support import toy

from labcli.core import registry
from labcli.core.protocol import load_protocol
from labcli.core.store import RunFile

PORT = f"sim://?mode={toy.MODE}&seed=3&clock=virtual"


@pytest.fixture
def acquired(toy_paper, tmp_path, invoke):
    run = tmp_path / "toy.h5"
    result = invoke("acquire", run, "--protocol", toy_paper, "--port", PORT, "--unattended")
    assert result.exit_code == 0, result.output
    return run, result


def test_the_registry_knows_the_toy_only_while_it_is_registered(toy_paper):
    assert registry.for_run_kind("toy").name == "toy"
    assert "toy" in registry.sim_modes() and "toy" in registry.protocol_kinds()
    registry.unregister("toy")
    assert "toy" not in registry.sim_modes()
    with pytest.raises(Exception, match="kind 'toy'"):
        registry.for_run_kind("toy")
    registry.register(toy.ToyPaper())  # the fixture's clean-up removes it again


def test_its_protocol_is_checked_by_the_core_loader_with_its_own_sections(toy_paper, tmp_path):
    p = load_protocol(toy_paper)
    assert p.kind == "toy" and p.channels == ("P", "ANG") and p.settings == {"masses_g": [200.0, 500.0]}
    assert p.calibration.units == ("MPa", "rad")
    bad = tmp_path / "bad.toml"
    bad.write_text(toy.PROTOCOL_TEXT.replace("masses_g = [200.0, 500.0]", "masses_g = [200.0]"), encoding="utf-8")
    with pytest.raises(Exception) as e:
        load_protocol(bad)
    assert str(e.value) == (
        f"{bad}: key 'load.masses_g' must be a list of two numbers [low, high] in g "
        "(the two trials' masses), not the list [200.0]."
    )


def test_acquire_records_two_trials_on_its_own_simulated_rig(acquired):
    run, result = acquired
    assert f"Session complete: 2 trials stored in {run}" in result.output
    with RunFile.open(run) as rf:
        assert rf.kind == "toy" and rf.channels == ("P", "ANG") and rf.records.ids() == [1, 2]
        for trial, mass in ((1, 0.2), (2, 0.5)):
            rec = rf.records.read(trial)
            # The rig's physics, read back through its ADC: 0.05 MPa and 10 deg per kg.
            assert rec["mass_kg"] == mass
            assert rec["P_MPa"] == pytest.approx(toy.P_REST_MPA + toy.P_PER_KG * mass, abs=2e-4)
            assert rec["theta_rad"] == pytest.approx(toy.ANGLE_PER_KG_RAD * mass, abs=math.radians(0.02))
            assert set(rec["raw"]) == {"baseline", "load"} and rec["raw"]["load"].counts.shape[1] == 2
            assert rec["settle"]["load"]["settled"] is True


def test_export_writes_its_table_and_import_reads_it_back(acquired, invoke, toy_paper, tmp_path):
    run, _ = acquired
    csv = tmp_path / "toy.csv"
    result = invoke("export", run, "-o", csv)
    assert result.exit_code == 0 and result.output == f"Wrote 2 trials from {run} to {csv}.\n"
    table = pd.read_csv(csv)
    assert list(table.columns) == ["trial", "mass_g", "P_MPa", "theta_deg"]
    assert table["mass_g"].tolist() == [200.0, 500.0]
    np.testing.assert_allclose(table["theta_deg"], [2.0, 5.0], atol=0.02)
    again = tmp_path / "again.h5"
    result = invoke("import", csv, "-o", again, "--protocol", toy_paper)
    assert result.exit_code == 0 and result.output == f"Imported 2 trials from {csv} into {again}.\n"
    csv2 = tmp_path / "again.csv"
    assert invoke("export", again, "-o", csv2).exit_code == 0
    assert csv2.read_bytes() == csv.read_bytes()


def test_inspect_describes_the_run(acquired, invoke):
    run, _ = acquired
    result = invoke("inspect", run)
    assert result.exit_code == 0
    lines = result.output.splitlines()
    assert lines[1] == "  kind        toy, protocol toy"
    assert lines[2].startswith("  rig         toy-rig-sim firmware 1.0 on sim://?mode=toy")
    assert "  trials      2 complete, 0 incomplete" in lines
    assert any(line.startswith("  settling    median ") and "over 2 trials" in line for line in lines)
    summary = invoke("inspect", run, "--json")
    assert '"kind": "toy"' in summary.output and '"complete": 2' in summary.output


def test_a_real_port_or_an_unknown_mode_is_refused_in_its_words(toy_paper, tmp_path, invoke):
    result = invoke("acquire", tmp_path / "x.h5", "--protocol", toy_paper, "--port", "sim://?mode=toys", "--unattended")
    assert result.exit_code == 1
    assert "option 'mode' in sim:// URL must be one of mckibben, rpam, toy, got 'toys'" in result.output


def test_a_record_type_must_give_its_four_hooks():
    from labcli.core.store.record_type import BaseRecordType

    class Half(BaseRecordType):
        def check(self, record, label, run):
            return record

        def read(self, row):
            return dict(row)

    with pytest.raises(TypeError, match="abstract methods from_row, table"):
        Half()
