"""The run file's redo journal (labcli.core.store.journal): one durable record per checkpoint.

A checkpoint makes only the journal durable; the run file is synced every few checkpoints and at
close.  So besides the kill tests (a killed process leaves its writes in the page cache), these
cut the power: the run file and the journal as the disk may hold them at any sync, i.e. what was
synced plus any part of what was written since, page by page, and check that the run opens with
every trial committed before the cut, bit for bit.
"""

from __future__ import annotations

import os
import random
import signal
import stat
import struct
import subprocess
import sys
from pathlib import Path

import pytest
from support.records import FakeDevice, FakeProtocol, assert_record_stored, make_record

from labcli.core.store import RunFile, journal
from labcli.core.store.journal import PAGE, journal_path

WRITER = Path(__file__).resolve().parents[1] / "support" / "records.py"
ROOT = Path(__file__).resolve().parents[2]


class Disk:
    """What each file held at its last sync (fsync or fdatasync), as the disk keeps it through a power cut."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch, folder: Path) -> None:
        self.synced: dict[int, bytes] = {}  # by inode: a run is built under another name, then linked in place
        self.cuts: list[tuple[int, dict[str, tuple[bytes | None, bytes]]]] = []  # (trials committed, files)
        self.committed = 0
        self.folder = str(folder)
        for name in ("fsync", "fdatasync"):
            real = getattr(os, name)
            monkeypatch.setattr(os, name, self._sync(real))

    def _sync(self, real):
        def sync(fd: int) -> None:
            path = os.readlink(f"/proc/self/fd/{fd}")
            if path.startswith(self.folder) and stat.S_ISREG(os.fstat(fd).st_mode):
                self.cuts.append((self.committed, self.state()))  # the power cut just before this sync
                real(fd)
                self.synced[os.fstat(fd).st_ino] = Path(f"/proc/self/fd/{fd}").read_bytes()
            else:
                real(fd)

        return sync

    def state(self) -> dict[str, tuple[bytes | None, bytes]]:
        """Every file of the folder: what its last sync left on disk (None: never synced), and what it holds now."""
        out = {}
        for name in os.listdir(self.folder):
            path = os.path.join(self.folder, name)
            out[path] = (self.synced.get(os.stat(path).st_ino), Path(path).read_bytes())
        return out


def after_cut(files: dict[str, tuple[bytes | None, bytes]], rng: random.Random) -> dict[str, bytes]:
    """Each file as a power cut may leave it: its synced bytes with any of the pages written since."""
    out = {}
    for path, (synced, now) in files.items():
        if synced is None and rng.random() < 0.5:
            continue  # never synced: its name may not have reached the disk at all
        old = synced or b""
        size = rng.choice([len(old), len(now)])
        image = bytearray(size)
        for at in range(0, size, PAGE):
            page = now[at : at + PAGE] if rng.random() < 0.5 else old[at : at + PAGE]
            image[at : at + len(page)] = page[: size - at]
        out[path] = bytes(image)
    return out


@pytest.mark.parametrize("seed", [1, 2])
def test_a_power_cut_at_any_sync_keeps_every_committed_trial(tmp_path: Path, monkeypatch, seed: int) -> None:
    folder = tmp_path / "rig"
    folder.mkdir()
    monkeypatch.setattr(journal, "SYNC_EVERY", 3)  # the run file synced (and the journal started again) mid-run
    disk = Disk(monkeypatch, folder)
    path = folder / "run.h5"
    with RunFile.create(path, protocol=FakeProtocol(), device_info=FakeDevice(), port="sim://") as run:
        for i in range(8):
            run.records.write(make_record(i, 40))
            disk.committed = i + 1
    monkeypatch.undo()
    rng = random.Random(seed)
    cuts = [(n, files) for n, files in disk.cuts if any(p.endswith("run.h5") for p in files)]
    assert len(cuts) >= 8
    checked = 0
    for k, (committed, files) in enumerate(cuts):
        for _ in range(2):
            # The cut in place: the journal names the run file by its inode, which a power cut keeps.
            for name in os.listdir(folder):
                if name != "run.h5":
                    os.unlink(folder / name)
            for p, data in after_cut(files, rng).items():
                with open(
                    folder / os.path.basename(p), "r+b" if (folder / os.path.basename(p)).exists() else "wb"
                ) as f:
                    f.truncate(0)
                    f.write(data)
            if committed == 0 and run_file_unreadable(path):
                continue  # cut while the run was first put in place: no trial was ever committed
            with RunFile.open(path, "a") as cut:  # the journal replayed first
                ids = cut.records.ids()
                assert ids[:committed] == list(range(committed)), (k, committed, ids)
                assert len(ids) in (committed, committed + 1)  # the trial being committed: whole or absent
                for i in ids:
                    assert_record_stored(cut.records.read(i), make_record(i, 40))
                cut.records.write(make_record(len(ids), 40))  # and the next writer goes on from there
            assert not os.path.exists(journal_path(str(path)))
            with RunFile.open(path) as cut:
                assert cut.records.ids() == list(range(len(ids) + 1)) and cut.verify()["ok"]
            checked += 1
    assert checked >= len(cuts)


def run_file_unreadable(path: Path) -> bool:
    try:
        with RunFile.open(path):
            return False
    except Exception:  # noqa: BLE001 - a run cut before its first sync holds anything
        return True


def test_a_kill_after_the_journal_is_durable_but_before_the_file_takes_it(tmp_path: Path) -> None:
    """The window the redo journal opens: a checkpoint is made once its record is synced, while the
    run file does not hold it yet (its pages not copied in, its new bytes not synced)."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))

    def run(path: Path, sync: int) -> subprocess.CompletedProcess:
        args = [sys.executable, str(WRITER), str(path), "4", "50", str(sync), "after-sync"]
        return subprocess.run(args, capture_output=True, env=env, text=True, timeout=120)

    total = int(run(tmp_path / "count.h5", 0).stdout.split("syncs ")[1])
    assert total >= 4
    for sync in range(1, total + 1):
        path = tmp_path / f"run{sync}.h5"
        proc = run(path, sync)
        assert proc.returncode == -signal.SIGKILL, proc.stderr
        stored = proc.stdout.count("stored ")
        assert os.path.exists(journal_path(str(path)))  # left behind, holding the checkpoint
        with RunFile.open(path) as cut:  # a reader replays it
            ids = cut.records.ids()
            assert ids == list(range(len(ids))) and len(ids) in (stored, stored + 1)
            for i in ids:
                assert_record_stored(cut.records.read(i), make_record(i, 50))
        assert not os.path.exists(journal_path(str(path)))
        with RunFile.open(path, "a") as cut:
            for i in range(len(ids), 4):
                cut.records.write(make_record(i, 50))
        with RunFile.open(path) as cut:
            assert cut.records.ids() == [0, 1, 2, 3] and cut.verify()["ok"]


# ------------------------------------------------------------------ the records themselves


def _journal_of(path: Path, checkpoints: list[list[tuple[int, bytes]]]) -> Path:
    """A journal for ``path`` holding one record per checkpoint (its writes ``(at, bytes)``), made by a JournalFile."""
    fd = os.open(path, os.O_RDWR)
    io = journal.JournalFile(fd, str(path))
    for writes in checkpoints:
        for at, data in writes:
            io.seek(at)
            io.write(data)
        io.checkpoint()
    os.close(io._jfd)  # as a kill leaves it: the journal in place
    os.close(fd)
    return Path(journal_path(str(path)))


def test_recovery_replays_every_whole_record_in_order_and_stops_at_a_torn_one(tmp_path: Path) -> None:
    path = tmp_path / "f.bin"
    path.write_bytes(bytes(3 * PAGE))
    where = _journal_of(path, [[(10, b"aaaa"), (5000, b"xx")], [(12, b"bb")], [(9000, b"cc")]])
    whole = where.read_bytes()
    path.write_bytes(bytes(3 * PAGE))  # the power cut: none of it in the file
    where.write_bytes(whole[:-3])  # the last record torn
    assert journal.recover(str(path))
    data = path.read_bytes()
    assert data[10:14] == b"aabb" and data[5000:5002] == b"xx" and data[9000:9002] == b"\0\0"
    assert not where.exists()


def test_records_of_another_generation_after_the_chain_are_not_replayed(tmp_path: Path) -> None:
    path = tmp_path / "f.bin"
    path.write_bytes(bytes(2 * PAGE))
    old = _journal_of(path, [[(0, b"old0")], [(100, b"old1")], [(200, b"old2")]]).read_bytes()
    synced = path.read_bytes()  # the file synced, holding the old records: the journal may start again
    new = _journal_of(path, [[(0, b"new0"), (100, b"mine")]]).read_bytes()  # shorter than the old one
    path.write_bytes(synced)  # the power cut: none of the new record in the file
    Path(journal_path(str(path))).write_bytes(new + old[len(new) :])  # the old records' tail still there
    assert journal.recover(str(path))
    data = path.read_bytes()
    assert data[0:4] == b"new0" and data[100:104] == b"mine" and data[200:204] == b"old2"


def test_a_journal_left_by_the_page_journal_before_it_is_still_replayed(tmp_path: Path) -> None:
    import hashlib

    path = tmp_path / "f.bin"
    path.write_bytes(bytes(2 * PAGE))
    st = os.stat(path)
    page = bytes([7]) * PAGE
    record = journal.OLD_HEADER.pack(journal.OLD_MAGIC, st.st_dev, st.st_ino, 1, 0) + struct.pack("<Q", 1) + page
    record += hashlib.blake2b(record, digest_size=journal.DIGEST).digest()
    Path(journal_path(str(path))).write_bytes(record)
    assert journal.recover(str(path))
    assert path.read_bytes() == bytes(PAGE) + page


def test_the_file_is_synced_every_few_checkpoints_and_the_journal_starts_again(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(journal, "SYNC_EVERY", 4)
    path = tmp_path / "f.bin"
    path.write_bytes(bytes(PAGE))
    fd = os.open(path, os.O_RDWR)
    io = journal.JournalFile(fd, str(path))
    syncs: list[str] = []
    real_fsync, real_fdatasync = os.fsync, os.fdatasync
    monkeypatch.setattr(os, "fsync", lambda f: (syncs.append("file" if f == fd else "other"), real_fsync(f)))
    monkeypatch.setattr(os, "fdatasync", lambda f: (syncs.append("journal"), real_fdatasync(f)))
    sizes = []
    for k in range(10):
        io.seek(8 * k)
        io.write(b"%08d" % k)
        io.checkpoint()
        sizes.append(io._jend)
    assert syncs.count("journal") == 10  # one sync a checkpoint ...
    assert syncs.count("file") == 2  # ... and the file's own every fourth (before the 5th and the 9th record)
    assert sizes[4] == sizes[0] and sizes[8] == sizes[0]  # the journal started again from its first byte
    io.close()
    assert syncs.count("file") == 3 and not os.path.exists(journal_path(str(path)))
    assert path.read_bytes()[:80] == b"".join(b"%08d" % k for k in range(10))


def test_a_checkpoint_copies_consecutive_kept_pages_in_one_write_each(tmp_path: Path, monkeypatch) -> None:
    path = tmp_path / "f.bin"
    path.write_bytes(bytes(8 * PAGE))  # no superblock: every byte is protected, every write kept
    fd = os.open(path, os.O_RDWR)
    io = journal.JournalFile(fd, str(path))
    expected = bytearray(8 * PAGE)
    for at, data in ((PAGE + 10, b"\x01" * (2 * PAGE)), (6 * PAGE + 5, b"\x02" * 100), (3 * PAGE, b"\x03" * 7)):
        io.seek(at)
        io.write(data)
        expected[at : at + len(data)] = data
    assert path.read_bytes() == bytes(8 * PAGE)  # nothing reaches the file before the checkpoint
    writes: list[tuple[int, int]] = []
    real = os.pwrite

    def counted(f: int, data: bytes, offset: int) -> int:
        if f == fd:
            writes.append((offset, len(data)))
        return real(f, data, offset)

    monkeypatch.setattr(os, "pwrite", counted)
    io.checkpoint()
    monkeypatch.undo()
    # Pages 1-3 in one write, page 6 in another.
    assert writes == [(PAGE, 3 * PAGE), (6 * PAGE, PAGE)]
    assert path.read_bytes() == bytes(expected)
    io.close()
    assert not os.path.exists(journal_path(str(path)))  # closed: the file holds it all
