"""The file a writer's HDF5 writes through: every checkpoint whole, or not at all.

HDF5 updates its own bookkeeping (object headers, B-tree nodes, the superblock's end of
file) in place, one ``pwrite`` at a time, lowest address first and the superblock last.
A kill between two of those writes left a file whose headers point at B-tree nodes never
written, or whose superblock's end of file lags metadata written past it: readers warned
of a metadata checksum, and the next writer failed with "addr overflow" or a wrong B-tree
signature.  So a writer does not give HDF5 the file; it gives it a :class:`JournalFile`
(h5py's ``fileobj`` driver), which

* writes straight to the file whatever lies past the end recorded in the superblock at the
  last checkpoint (nothing on disk points there yet: new chunks, new nodes, new headers),
  and notes where;
* keeps in memory, in 4 KiB pages, every write to bytes before that end (the bookkeeping
  that points at the new things), and reads see those pages;
* at :meth:`JournalFile.checkpoint`: appends one record to the journal next to the run
  (``.<name>.labcli-journal``), holding every byte changed since the last checkpoint (the
  new bytes, read back from the file, and of the kept pages the bytes that differ from the
  file's: HDF5 rewrites a whole B-tree node to add one entry), the file's identity, the
  journal's generation and the record's place in it, and a checksum; makes the journal
  durable (one ``fdatasync``: the checkpoint is made), then copies the pages into the
  file.  The file itself is not synced: it is synced every :data:`SYNC_EVERY` checkpoints
  (or when the journal would outgrow :data:`JOURNAL_MAX`, or the file size limit) and at
  close, and only then does the journal start again from its first byte, under a new
  generation, or go.  A journal that meets a full disk starts again the same way before it
  gives up: a record that fits in the room it already holds is written there.

The crash argument.  Let S_k be the file as checkpoint k left it, and B the file as it was
when last synced (every record in the journal came after B).  Every byte a checkpoint k
changed, below or past the recorded end, is in record k, with its value in S_k (a byte
HDF5 wrote with the value it had is unchanged: S_k holds it as S_k-1 did).  What a
kill or a power cut leaves on disk is B changed by any part of the writes made since, torn
anywhere, and a journal whose records from the first are whole up to some record n (the
last whose ``fdatasync`` returned, at least), the rest torn, stale (another generation, a
wrong place) or missing.  Recovery (:func:`replay`, by whoever opens the file next when no
writer holds it, reader or writer) writes records 1..n in order, syncs the file, and
removes the journal.  After it, a byte some record wrote holds its value in the last such
record, which is its value in S_n; a byte none wrote was not changed by checkpoints 1..n,
so it holds its value in B, which is its value in S_n, unless the writes after checkpoint
n changed it -- and those go straight to the file only past S_n's recorded end (bytes S_n
does not reach), never before it (kept in memory until the next record is durable).  So
the file reads as S_n, whole.  Replaying records the file already holds is harmless for
the same reason; so is replaying an old generation's records the file was synced after
(its bytes are B's or rewritten by the records that follow).  A journal starts again only
after the file is synced: nothing before that sync is needed from it any more, and a
record of the new generation that is torn or missing stops the replay at once (the stale
records after it are of another generation).

A file built under a temporary name (:mod:`.space`) is not journaled until it is put in
place: it is synced once, whole, just before (a kill before then leaves a ``.partial`` file,
removed at the next start).
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import hashlib
import os
import resource
import secrets
import struct

import numpy as np

PAGE = 4096
MAGIC = b"LABCLIJ2"
RECORD = struct.Struct("<8sQQQQQ")  # magic, device, inode, generation, place, bytes of extents
EXTENT = struct.Struct("<QQ")  # where, how many bytes
GAP = 32  # unchanged bytes between two changed ones that a record holds rather than start another extent
OLD_MAGIC = b"LABCLIJ1"  # one record of pages, written by labcli before the redo journal
OLD_HEADER = struct.Struct("<8sQQQQ")  # magic, device, inode, page count, superblock end
SUFFIX = ".labcli-journal"
DIGEST = 16
SYNC_EVERY = 32  # checkpoints between two syncs of the file itself
JOURNAL_MAX = 8 << 20  # bytes of journal before the file is synced and the journal starts again


def journal_path(path: str) -> str:
    """Where the journal of the run file at ``path`` lives (beside it, hidden)."""
    folder, name = os.path.split(os.path.abspath(path))
    return os.path.join(folder, f".{name}{SUFFIX}")


def superblock_end(read: bytes) -> int | None:
    """The end of file a version 2 or 3 superblock records (``read``: the file's first 48 bytes), or None."""
    if len(read) < 48 or read[:8] != b"\x89HDF\r\n\x1a\n" or read[8] not in (2, 3) or read[9] != 8:
        return None
    return int.from_bytes(read[28:36], "little")


def lock(fd: int, path: str, busy: str) -> None:
    """Take the exclusive lock every labcli writer takes (HDF5's own ``flock``); ``busy`` when held."""
    from ...errors import StoreError

    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError as e:
        if e.errno in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
            raise StoreError(f"{path} {busy}.") from None
        # A file system without locks (some network mounts): go on without, as HDF5 advises.


class JournalFile:
    """The file-like object HDF5 reads and writes a run through (see the module docstring).

    ``fd``: the run file, open read-write and locked; ``journaled``: False while the file is
    built under a temporary name (every write goes straight to it, every checkpoint syncs it).
    """

    def __init__(self, fd: int, path: str, journaled: bool = True) -> None:
        self.fd = fd
        self.path = path
        self.pos = 0
        self.pages: dict[int, bytearray] = {}
        self.before: dict[int, bytes] = {}  # each kept page as the file held it
        self.extents: list[tuple[int, int]] = []  # written straight to the file since the last checkpoint
        self.journaled = journaled
        self.durable_end = self._recorded_end() if journaled else 0
        self.written_end = 0  # the furthest byte written (the room to reserve starts there)
        self.unsynced = 0  # records in the journal the file's last sync came before
        self._jfd: int | None = None
        self._jend = 0  # where the next record goes
        self._generation = 0
        self._place = 0

    # ------------------------------------------------------------ what h5py's driver calls

    def seek(self, offset: int, whence: int = os.SEEK_SET) -> int:
        if whence == os.SEEK_END:
            self.pos = self.size() + offset
        elif whence == os.SEEK_CUR:
            self.pos += offset
        else:
            self.pos = offset
        return self.pos

    def tell(self) -> int:
        return self.pos

    def read(self, n: int = -1) -> bytes:
        if n < 0:
            n = max(0, self.size() - self.pos)
        out = bytearray(os.pread(self.fd, n, self.pos))
        if len(out) < n:  # past the end reads as zeros, as HDF5's own driver reads it
            out.extend(bytes(n - len(out)))
        if self.pages:
            self._overlay(out, self.pos)
        self.pos += n
        return bytes(out)

    def write(self, data: bytes | bytearray | memoryview) -> int:
        b = memoryview(data).cast("B")
        n = len(b)
        self.written_end = max(self.written_end, self.pos + n)
        if self.journaled and self.pos < self.durable_end:
            self._keep(self.pos, b)
        else:
            if self.journaled:
                self.extents.append((self.pos, n))
            done = 0
            while done < n:
                done += os.pwrite(self.fd, b[done:], self.pos + done)
            if self.pages:
                self._keep(self.pos, b, only_kept=True)
        self.pos += n
        return n

    def truncate(self, size: int | None = None) -> int:
        # HDF5 asks at every flush; the room reserved past the end stays until the file is closed.
        return self.pos if size is None else size

    def flush(self) -> None:
        pass

    # ------------------------------------------------------------ checkpoints

    def size(self) -> int:
        return os.fstat(self.fd).st_size

    def end(self) -> int:
        """Where HDF5's next bytes go, about (what follows may be only reserved room)."""
        return max(self.written_end, self.recorded_end() or 0)

    def checkpoint(self, publishing: bool = False) -> None:
        """Make everything written so far durable, as one change (see the module docstring).

        A file built under a temporary name is synced once, whole, when it is about to be put in
        place (``publishing``): until then a kill leaves a partial file nobody reads (removed at
        the next start), so a sync at each of its checkpoints would buy nothing.
        """
        if not self.journaled:
            if publishing:
                os.fsync(self.fd)
            return
        if not self.pages and not self.extents:
            return
        record = self._record()
        if record:  # else every byte written holds the value it had: nothing changed
            self._append(record)  # durable: the checkpoint is made
        for first, pages in _runs(self.pages):  # consecutive pages in one write (HDF5's nodes lie together)
            _pwrite_all(self.fd, pages[0] if len(pages) == 1 else b"".join(pages), first * PAGE)
        self.pages.clear()
        self.before.clear()
        self.extents.clear()
        self.unsynced += 1
        self.durable_end = self._recorded_end()

    def discard(self) -> None:
        """Forget what was written since the last checkpoint (a write that failed half-way)."""
        self.pages.clear()
        self.before.clear()
        self.extents.clear()

    def start_journal(self, path: str) -> None:
        """The file is in place at ``path`` (and synced): from here on, checkpoints are journaled."""
        self.path = path
        self.journaled = True
        self.extents.clear()
        self.durable_end = self._recorded_end()

    def close(self, end: int | None = None) -> None:
        """Sync the file, remove the journal (the file holds it all), give back the room past ``end``."""
        try:
            if self.unsynced:
                os.fsync(self.fd)  # the journal goes only once what it holds is durable in the file
                self.unsynced = 0
        finally:
            if self._jfd is not None:
                os.close(self._jfd)
                self._jfd = None
        with contextlib.suppress(FileNotFoundError):
            os.unlink(journal_path(self.path))
        if end is not None and self.size() > end:
            with contextlib.suppress(OSError):
                os.ftruncate(self.fd, end)
        os.close(self.fd)

    # ------------------------------------------------------------ the journal

    def _record(self) -> bytes:
        """A record's extents: every byte written since the last checkpoint, as it stands now.

        The new bytes whole (read back, the kept pages laid over them); of the kept pages, the
        runs of bytes that differ from what the file holds (HDF5 rewrites a whole B-tree node or
        header to change a few entries: a byte rewritten with its own value changed nothing).
        """
        parts: list[bytes] = []
        if self.pages:
            order = sorted(self.pages)
            new = np.frombuffer(b"".join(self.pages[p] for p in order), dtype=np.uint8)
            old = np.frombuffer(b"".join(self.before[p] for p in order), dtype=np.uint8)
            changed = np.flatnonzero(new != old)
            if changed.size:
                # One run per stretch of changes less than GAP bytes apart, never across a page.
                cut = np.flatnonzero((np.diff(changed) > GAP) | (np.diff(changed // PAGE) != 0))
                firsts = changed[np.concatenate(([0], cut + 1))].tolist()
                lasts = changed[np.concatenate((cut, [changed.size - 1]))].tolist()
                for a, b in zip(firsts, lasts, strict=True):
                    at = order[a // PAGE] * PAGE + a % PAGE
                    parts += (EXTENT.pack(at, b + 1 - a), new[a : b + 1].tobytes())
        for at, n in _merged(self.extents):
            parts += (EXTENT.pack(at, n), self._peek(at, n))
        return b"".join(parts)

    def _append(self, data: bytes) -> None:
        """Add a record to the journal and make it durable (the journal starts again first when full)."""
        size = RECORD.size + len(data) + DIGEST
        limit = _file_size_limit()
        if self._jend and (
            self.unsynced >= SYNC_EVERY
            or self._jend + size > JOURNAL_MAX
            or (limit is not None and self._jend + size > limit)
        ):
            self._start_again()
        where = journal_path(self.path)
        new = self._jfd is None and not os.path.exists(where)
        if self._jfd is None:
            self._jfd = os.open(where, os.O_WRONLY | os.O_CREAT, 0o644)
        try:
            os.posix_fallocate(self._jfd, self._jend, size)  # a full disk stops it here, the file untouched
        except OSError as e:
            if not self._jend or e.errno not in (errno.ENOSPC, errno.EDQUOT, errno.EFBIG):
                raise
            self._start_again()  # the room the journal holds already is enough for one record
            os.posix_fallocate(self._jfd, 0, size)
        if self._jend == 0:
            self._generation = int.from_bytes(secrets.token_bytes(8), "little")
            self._place = 0
        st = os.fstat(self.fd)
        head = RECORD.pack(MAGIC, st.st_dev, st.st_ino, self._generation, self._place, len(data))
        digest = hashlib.blake2b(head, digest_size=DIGEST)
        digest.update(data)
        _pwrite_all(self._jfd, head + data + digest.digest(), self._jend)
        os.fdatasync(self._jfd)
        if new:
            _sync_folder(where)
        self._jend += size
        self._place += 1

    def _start_again(self) -> None:
        """Sync the file, which then holds every record so far, so the journal may start again from its first byte."""
        os.fsync(self.fd)
        self.unsynced = 0
        self._jend = 0

    # ------------------------------------------------------------ inside

    def recorded_end(self) -> int | None:
        """The end of file the superblock on disk (or about to be) records."""
        return superblock_end(self._peek(0, 48))

    def _recorded_end(self) -> int:
        # A superblock this module does not parse: everything in the file so far is protected.
        end = self.recorded_end()
        return self.size() if end is None else end

    def _peek(self, at: int, n: int) -> bytes:
        out = bytearray(os.pread(self.fd, n, at))
        out.extend(bytes(n - len(out)))
        if self.pages:
            self._overlay(out, at)
        return bytes(out)

    def _page(self, p: int) -> bytearray:
        page = self.pages.get(p)
        if page is None:
            page = bytearray(os.pread(self.fd, PAGE, p * PAGE))
            page.extend(bytes(PAGE - len(page)))
            self.pages[p] = page
            self.before[p] = bytes(page)
        return page

    def _keep(self, at: int, b: memoryview, only_kept: bool = False) -> None:
        """Copy ``b`` (to go at ``at``) into the pages kept in memory (``only_kept``: those already kept)."""
        end = at + len(b)
        first = at // PAGE
        if (end - 1) // PAGE == first:  # most of HDF5's rewrites: a header or a node within one page
            page = self.pages.get(first)
            if page is None:
                if only_kept:
                    return
                page = self._page(first)
            page[at - first * PAGE : end - first * PAGE] = b
            return
        for p in range(first, (end - 1) // PAGE + 1):
            if only_kept and p not in self.pages:
                continue
            page = self._page(p)
            lo, hi = max(at, p * PAGE), min(end, (p + 1) * PAGE)
            page[lo - p * PAGE : hi - p * PAGE] = b[lo - at : hi - at]

    def _overlay(self, out: bytearray, at: int) -> None:
        end = at + len(out)
        for p in range(at // PAGE, (end - 1) // PAGE + 1 if end > at else at // PAGE):
            page = self.pages.get(p)
            if page is None:
                continue
            lo, hi = max(at, p * PAGE), min(end, (p + 1) * PAGE)
            out[lo - at : hi - at] = page[lo - p * PAGE : hi - p * PAGE]


def recover(path: str) -> bool:
    """Replay the journal a killed writer left beside ``path`` (True when it did); drop a torn one.

    Only when no writer holds the file and it may be written: a live writer's journal is its own.
    """
    where = journal_path(path)
    if not os.path.exists(where):
        return False
    try:
        fd = os.open(path, os.O_RDWR)
    except OSError:
        return False
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as e:
            if e.errno in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                return False
        return replay(fd, where)
    finally:
        os.close(fd)


def replay(fd: int, where: str) -> bool:
    """Write a journal's whole records into the file ``fd`` (held locked), in order, then remove the journal."""
    try:
        with open(where, "rb") as j:
            journal = j.read()
    except FileNotFoundError:
        return False
    writes = records(journal, os.fstat(fd))
    if writes:
        for at, data in writes:
            _pwrite_all(fd, data, at)
        os.fsync(fd)
    with contextlib.suppress(FileNotFoundError):
        os.unlink(where)
    _sync_folder(where)
    return bool(writes)


def records(journal: bytes, st: os.stat_result) -> list[tuple[int, bytes]]:
    """The writes of a journal of this file (by device and inode), in order: every record of the
    first one's generation, each in its place, up to the first torn, stale or foreign one."""
    if journal[:8] == OLD_MAGIC:
        return _old_pages(journal, st)
    out: list[tuple[int, bytes]] = []
    at, place, generation = 0, 0, None
    while len(journal) - at >= RECORD.size + DIGEST:
        magic, dev, ino, gen, where, extents = RECORD.unpack_from(journal, at)
        size = RECORD.size + extents
        if magic != MAGIC or (dev, ino) != (st.st_dev, st.st_ino) or where != place:
            break
        if generation is not None and gen != generation or len(journal) - at < size + DIGEST:
            break
        digest = hashlib.blake2b(memoryview(journal)[at : at + size], digest_size=DIGEST).digest()
        if digest != journal[at + size : at + size + DIGEST]:
            break
        k = at + RECORD.size
        while k < at + size:
            there, n = EXTENT.unpack_from(journal, k)
            out.append((there, journal[k + EXTENT.size : k + EXTENT.size + n]))
            k += EXTENT.size + n
        generation, place, at = gen, place + 1, at + size + DIGEST
    return out


def _old_pages(record: bytes, st: os.stat_result) -> list[tuple[int, bytes]]:
    """The pages of a whole journal written before the redo journal; none for a torn or foreign one."""
    if len(record) < OLD_HEADER.size + DIGEST:
        return []
    magic, dev, ino, count, _ = OLD_HEADER.unpack_from(record)
    size = OLD_HEADER.size + count * (8 + PAGE)
    if magic != OLD_MAGIC or (dev, ino) != (st.st_dev, st.st_ino) or len(record) < size + DIGEST:
        return []
    if hashlib.blake2b(record[:size], digest_size=DIGEST).digest() != record[size : size + DIGEST]:
        return []
    out = []
    for k in range(count):
        at = OLD_HEADER.size + k * (8 + PAGE)
        (p,) = struct.unpack_from("<Q", record, at)
        out.append((p * PAGE, record[at + 8 : at + 8 + PAGE]))
    return out


def _merged(extents: list[tuple[int, int]]) -> list[tuple[int, int]]:
    """The byte ranges ``(at, n)`` covered, overlapping and touching ones joined, in order."""
    out: list[list[int]] = []
    for at, n in sorted(extents):
        if out and at <= out[-1][0] + out[-1][1]:
            out[-1][1] = max(out[-1][1], at + n - out[-1][0])
        else:
            out.append([at, n])
    return [(at, n) for at, n in out]


def _runs(pages: dict[int, bytearray]) -> list[tuple[int, list[bytearray]]]:
    """The kept pages in runs of consecutive page numbers: (first page, the run's pages in order)."""
    out: list[tuple[int, list[bytearray]]] = []
    for p in sorted(pages):
        if out and out[-1][0] + len(out[-1][1]) == p:
            out[-1][1].append(pages[p])
        else:
            out.append((p, [pages[p]]))
    return out


def _file_size_limit() -> int | None:
    limit = resource.getrlimit(resource.RLIMIT_FSIZE)[0]
    return None if limit == resource.RLIM_INFINITY else int(limit)


def _pwrite_all(fd: int, data: bytes | bytearray, at: int) -> None:
    view = memoryview(data)
    done = 0
    while done < len(view):
        done += os.pwrite(fd, view[done:], at + done)


def _sync_folder(path: str) -> None:
    with contextlib.suppress(OSError):
        fd = os.open(os.path.dirname(os.path.abspath(path)) or ".", os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
