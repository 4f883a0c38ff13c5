"""``labcli.read_run``: the records of a run file of any kind as one DataFrame, with its kind,
units and provenance in ``attrs`` (the library's door for a run whose kind the reader does not know)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pandas as pd
import pytest

import labcli
from labcli.core.store import RunFile
from labcli.errors import LabcliError

SAMPLES = Path(__file__).resolve().parents[2] / "sample_runs"
KINDS = {"force": "force", "pushes": "push", "joint": "rpam-joint", "stretch": "rpam-stretch"}


@pytest.mark.parametrize("name", sorted(KINDS))
def test_each_kind_reads_as_its_export_table(name, tmp_path):
    run = tmp_path / f"{name}.h5"
    shutil.copy(SAMPLES / f"{name}.h5", run)
    df = labcli.read_run(run)
    with RunFile.open(run) as rf:
        expected = rf.records.table()
        n = len(rf.records.ids())
    assert df.attrs["kind"] == KINDS[name] and len(df) == n > 0
    pd.testing.assert_frame_equal(df, expected)
    units = df.attrs["units"]
    assert units and set(units) <= set(df.columns) and all(u for u in units.values())
    assert df.attrs["provenance"]["file"] == run.name and df.attrs["provenance"]["kind"] == KINDS[name]


def test_it_agrees_with_load_trials_and_adds_every_records_columns(tmp_path):
    run = tmp_path / "force.h5"
    shutil.copy(SAMPLES / "force.h5", run)
    pd.testing.assert_frame_equal(labcli.read_run(run), labcli.load_trials(run))
    wide = labcli.read_run(run, all_columns=True)
    assert {"accepted", "loaded_settle_time_s"} <= set(wide.columns) and len(wide.columns) > 30


def test_a_file_that_is_no_run_is_one_sentence(tmp_path):
    bad = tmp_path / "notes.h5"
    bad.write_bytes(b"not hdf5 at all")
    with pytest.raises(LabcliError) as e:
        labcli.read_run(bad)
    assert str(bad) in str(e.value) and "\n" not in str(e.value)
