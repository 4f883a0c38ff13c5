"""Tables written a row a commit grow 64 rows at a time, and give back the rows never written.

A trial table of one-row chunks changed every column's extent at every commit (each dataset's
header rewritten, flushed and journaled).  Its columns now grow ahead of the writes; the rows
past ``@committed`` were never part of the table, and closing the file gives back those never
written, so a reader with h5py alone sees the rows written, as before.
"""

from __future__ import annotations

import shutil

import h5py
import numpy as np
import pytest
from support.records import FakeDevice, FakeProtocol, assert_record_stored, make_record

from labcli.core.store import RunFile
from labcli.core.store.columns import GROW
from labcli.errors import LabcliWarning


def new_run(path: str) -> RunFile:
    return RunFile.create(path, protocol=FakeProtocol(), device_info=FakeDevice(), port="sim://?seed=1")


def lengths(path: str, table: str = "entry/trials") -> set[int]:
    with h5py.File(path, "r") as f:
        t = f[table]
        return {int(t[name].shape[0]) for name in t if isinstance(t[name], h5py.Dataset)}


def test_columns_grow_ahead_while_written_and_hold_the_rows_written_once_closed(tmp_path) -> None:
    path, copy = str(tmp_path / "run.h5"), str(tmp_path / "copy.h5")
    recs = [make_record(i) for i in range(1, 4)]
    with new_run(path) as run:
        for rec in recs:
            run.records.write(rec)
        shutil.copyfile(path, copy)  # what a kill here leaves (each commit's checkpoint is in the file)
    assert lengths(copy) == {GROW}
    assert lengths(path) == {3}
    for p in (path, copy):
        with RunFile.open(p) as run:
            assert run.records.ids() == [1, 2, 3]
            assert run.records.columns().damaged == [] and run.records.columns().incomplete == []
            for rec in recs:
                assert_record_stored(run.records.read(rec["trial"]), rec)


def test_a_file_left_grown_takes_more_records_and_closes_trimmed(tmp_path) -> None:
    path, copy = str(tmp_path / "run.h5"), str(tmp_path / "copy.h5")
    with new_run(path) as run:
        run.records.write(make_record(1))
        shutil.copyfile(path, copy)
    with RunFile.open(copy, mode="a") as run:
        for i in range(2, GROW + 3):  # past the first GROW rows: grown once more
            run.records.write(make_record(i))
    assert lengths(copy) == {GROW + 2}
    with RunFile.open(copy) as run:
        assert run.records.ids() == list(range(1, GROW + 3))


def test_a_damaged_committed_count_reads_the_rows_written_not_the_rows_grown(tmp_path) -> None:
    path, copy = str(tmp_path / "run.h5"), str(tmp_path / "copy.h5")
    with new_run(path) as run:
        for i in range(1, 4):
            run.records.write(make_record(i))
        shutil.copyfile(path, copy)
    with h5py.File(copy, "r+") as f:  # @committed no longer matches its checksum
        f["entry/trials"].attrs.modify("committed_checksum", np.uint64(12345))
        assert f["entry/trials/trial"].shape[0] == GROW
    with RunFile.open(copy) as run, pytest.warns(LabcliWarning, match="1 damaged record is left out") as w:
        assert run.records.ids() == [1, 2, 3]
        damaged = run.records.columns().damaged
    # The count alone: none of the rows grown ahead and never written is named.
    assert len(damaged) == 1 and "committed row count does not match its checksum" in damaged[0][1]
    assert len(w) == 1
