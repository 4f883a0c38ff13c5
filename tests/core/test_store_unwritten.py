"""A row's empty columns are left unwritten where no row was ever held; frames chunked by window length.

A trial leaves about half of its table's columns empty (no flags, no baseline settling, no
plan), and each such column was a chunk written, indexed and journaled at every commit.  Rows
the writer grew itself were never written by anyone: an empty column is left unwritten there
and reads back as its fill, checking the same.  Rows a file already held past ``@committed``
(what an older labcli killed mid-commit left, with no journal to undo it) are written whole.
"""

from __future__ import annotations

import h5py
import numpy as np
import pytest
from support.records import FakeDevice, FakeProtocol, assert_record_stored, make_record

from labcli.core.store import RunFile
from labcli.core.store.frames import SIDE_BY_SIDE, chunk_frames


def new_run(path: str, protocol: object = None) -> RunFile:
    return RunFile.create(path, protocol=protocol or FakeProtocol(), device_info=FakeDevice(), port="sim://?seed=1")


def allocated(ds: h5py.Dataset, row: int) -> bool:
    info = ds.id.get_chunk_info_by_coord((row, *(0,) * (ds.ndim - 1)))
    return info.byte_offset is not None and info.size > 0


def test_empty_columns_of_new_rows_are_left_unwritten_and_read_back_as_written(tmp_path) -> None:
    path = str(tmp_path / "run.h5")
    recs = [make_record(i) for i in range(1, 5)]
    with new_run(path) as run:
        for rec in recs:
            run.records.write(rec)
    with h5py.File(path, "r") as f:
        t = f["entry/trials"]
        for row in range(4):
            assert not allocated(t["flags"], row)  # no flags given: the fill, never written
            assert allocated(t["trial"], row) and allocated(t["checksum"], row)
        assert [bytes(v) for v in t["flags"][:]] == [b""] * 4  # what h5py alone reads: the fill
        assert np.array_equal(t["trial"][:], [1, 2, 3, 4])
    with RunFile.open(path) as run:
        cols = run.records.columns()
        assert cols.damaged == [] and run.records.ids() == [1, 2, 3, 4]
        for rec in recs:
            stored = run.records.read(rec["trial"])
            assert_record_stored(stored, rec)
            assert stored["flags"] == []


def test_a_row_left_past_committed_is_written_whole_where_the_new_record_is_empty(tmp_path) -> None:
    path = str(tmp_path / "run.h5")
    with new_run(path) as run:
        run.records.write(make_record(1))
    # What a writer without the journal, killed after writing its row and before moving
    # @committed, left: every column of row 1 written, flags among them, the count still 1.
    with h5py.File(path, "r+") as f:
        t = f["entry/trials"]
        for name in t:
            ds = t[name]
            ds.resize(2, axis=0)
            ds[1] = ds[0]
        t["flags"][1] = b"a note of a record never committed"
        assert int(t.attrs["committed"]) == 1
    rec = make_record(2)
    with RunFile.open(path, mode="a") as run:
        run.records.write(rec)
    with RunFile.open(path) as run:
        assert run.records.columns().damaged == [] and run.records.ids() == [1, 2]
        stored = run.records.read(2)
        assert_record_stored(stored, rec)
        assert stored["flags"] == []
    with h5py.File(path, "r") as f:
        assert bytes(f["entry/trials/flags"][1]) == b""  # the leftover note written over


class Capture:
    def __init__(self, frames: int) -> None:
        self.capture_s = frames / 1000.0


@pytest.mark.parametrize("frames", [400, 4000])
def test_short_windows_keep_the_channels_in_one_chunk_and_long_ones_apart(tmp_path, frames) -> None:
    protocol = FakeProtocol()
    protocol.rate_hz = 1000.0  # type: ignore[attr-defined]
    protocol.settling = Capture(frames)  # type: ignore[attr-defined]
    chunk = chunk_frames(frames)
    path = str(tmp_path / "run.h5")
    recs = [make_record(i, n=frames) for i in (1, 2)]
    with new_run(path, protocol) as run:
        for rec in recs:
            run.records.write(rec)
    with h5py.File(path, "r") as f:
        raw = f["entry/raw"]
        width = len(FakeProtocol().channels) if chunk <= SIDE_BY_SIDE else 1
        assert raw["values"].chunks == (chunk, width) and raw["counts"].chunks == (chunk, width)
    with RunFile.open(path) as run:
        for rec in recs:
            assert_record_stored(run.records.read(rec["trial"]), rec)


def test_room_is_reserved_ahead_so_most_commits_ask_the_disk_nothing(tmp_path, monkeypatch) -> None:
    from labcli.core.store import space

    calls: list[int] = []
    real = space.os.posix_fallocate

    def counted(fd: int, offset: int, length: int) -> None:
        calls.append(fd)
        real(fd, offset, length)

    path = str(tmp_path / "run.h5")
    with new_run(path) as run:
        monkeypatch.setattr(space.os, "posix_fallocate", counted)
        for i in range(1, 11):
            run.records.write(make_record(i))
        fd = run.io.fd
        monkeypatch.undo()
    # Ten trials, each two windows and a commit: thirty reservations, one asked of the disk.
    assert calls.count(fd) == 1
    with RunFile.open(path) as run:
        assert run.records.ids() == list(range(1, 11))


def test_near_the_size_limit_a_commit_takes_just_the_room_it_needs(tmp_path, monkeypatch) -> None:
    from labcli.core.store import space, writer
    from labcli.errors import DiskFull

    path = str(tmp_path / "run.h5")
    with new_run(path) as run:
        end = run.io.end()
        # Room for two trials and HDF5's slack, not for the megabyte reserved ahead.
        monkeypatch.setattr(space, "file_size_limit", lambda: end + space.SLACK + writer.AHEAD // 2)
        run.records.write(make_record(1))
        run.records.write(make_record(2))
        assert run.io.end() < end + writer.AHEAD // 2
        monkeypatch.setattr(space, "file_size_limit", lambda: run.io.end() + 1024)
        with pytest.raises(DiskFull, match=r"ulimit -f.*the 2 trials stored before are intact"):
            run.records.write(make_record(3))
        monkeypatch.undo()
    with RunFile.open(path) as run:
        assert run.records.ids() == [1, 2]
        assert_record_stored(run.records.read(2), make_record(2))


def test_a_writer_counts_the_frames_it_grew_as_the_file_holds_them(tmp_path) -> None:
    path = str(tmp_path / "run.h5")
    with new_run(path) as run:
        frames = run.tables.frames
        for i in (1, 2, 3):
            run.records.write(make_record(i, n=70))
            held = int(frames.time.shape[0])
            assert frames.extent == held == frames.next_start() - (-held % frames.chunk)
        w = run.windows.begin()
        w.append(np.arange(5) * 1e-3, np.arange(5), np.ones((5, 6)), np.ones((5, 6)))
        stored = w.finish()
        assert stored.stored is not None and stored.stored.start == held + (-held % frames.chunk)
        assert frames.extent == int(frames.time.shape[0]) == stored.stored.stop
    with RunFile.open(path) as run:
        assert run.tables.frames.extent == stored.stored.stop
