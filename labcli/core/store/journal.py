"""The file a writer's HDF5 writes through: every checkpoint whole, or not at all.

HDF5 updates its own bookkeeping (object headers, B-tree nodes, the superblock's end of
file) in place, one ``pwrite`` at a time, lowest address first and the superblock last.
A kill between two of those writes left a file whose headers point at B-tree nodes never
written, or whose superblock's end of file lags metadata written past it: readers warned
of a metadata checksum, and the next writer failed with "addr overflow" or a wrong B-tree
signature.  So a writer does not give HDF5 the file; it gives it a :class:`JournalFile`
(h5py's ``fileobj`` driver), which

* writes straight to the file whatever lies past the end recorded in the superblock at the
  last checkpoint (nothing on disk points there yet: new chunks, new nodes, new headers);
* keeps in memory, in 4 KiB pages, every write to bytes before that end (the bookkeeping
  that points at the new things), and reads see those pages;
* at :meth:`JournalFile.checkpoint`: fsyncs the file (the new things are on disk, and the
  pages the last checkpoint copied in), writes the pages to the journal next to the run
  (``.<name>.labcli-journal``, with the file's identity and a checksum) and fsyncs it, then
  copies them into the file.  Those copies are made durable by the next checkpoint's first
  fsync (or at close), before the journal that holds them is overwritten or removed: two
  fsyncs a checkpoint, not three.

A kill before the journal is whole leaves the file as the last checkpoint left it (the
torn journal fails its checksum and is dropped); a kill after it is replayed by whoever
opens the file next (:func:`recover`), reader or writer, when no writer holds it.
Replaying the last journal twice is harmless: its pages are what the file holds after it.

A file built under a temporary name (:mod:`.space`) is not journaled until it is put in
place: a kill before then leaves a ``.partial`` file, removed at the next start.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import hashlib
import os
import struct

PAGE = 4096
MAGIC = b"LABCLIJ1"
HEADER = struct.Struct("<8sQQQQ")  # magic, device, inode, page count, superblock end
SUFFIX = ".labcli-journal"
DIGEST = 16


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
    built under a temporary name (every write goes straight to it).
    """

    def __init__(self, fd: int, path: str, journaled: bool = True) -> None:
        self.fd = fd
        self.path = path
        self.pos = 0
        self.pages: dict[int, bytearray] = {}
        self.journaled = journaled
        self.durable_end = self._recorded_end() if journaled else 0
        self.written_end = 0  # the furthest byte written (the room to reserve starts there)
        self.copied = False  # pages copied in since the last fsync: the journal still holds them

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

    def checkpoint(self) -> None:
        """Make everything written so far durable, as one change (see the module docstring)."""
        os.fsync(self.fd)
        self.copied = False
        if not self.pages:
            self.durable_end = self._recorded_end() if self.journaled else 0
            return
        where = journal_path(self.path)
        st = os.fstat(self.fd)
        order = sorted(self.pages)
        body = b"".join(struct.pack("<Q", p) + bytes(self.pages[p]) for p in order)
        head = HEADER.pack(MAGIC, st.st_dev, st.st_ino, len(order), 0)
        record = head + body
        record += hashlib.blake2b(record, digest_size=DIGEST).digest()
        new = not os.path.exists(where)
        jfd = os.open(where, os.O_WRONLY | os.O_CREAT, 0o644)
        try:
            os.posix_fallocate(jfd, 0, len(record))  # a full disk stops it here, the file untouched
            _pwrite_all(jfd, record, 0)
            os.fsync(jfd)
        finally:
            os.close(jfd)
        if new:
            _sync_folder(where)
        for p in order:
            _pwrite_all(self.fd, self.pages[p], p * PAGE)
        self.copied = True  # synced by the next checkpoint's first fsync, or at close
        self.pages.clear()
        self.durable_end = self._recorded_end()

    def discard(self) -> None:
        """Forget what was written since the last checkpoint (a write that failed half-way)."""
        self.pages.clear()

    def start_journal(self, path: str) -> None:
        """The file is in place at ``path`` now: from here on, checkpoints are journaled."""
        self.path = path
        self.journaled = True
        self.durable_end = self._recorded_end()

    def close(self, end: int | None = None) -> None:
        """Remove the journal (the last checkpoint is in the file), give back the room past ``end``."""
        if self.copied:
            os.fsync(self.fd)  # the journal goes only once what it holds is durable in the file
            self.copied = False
        with contextlib.suppress(FileNotFoundError):
            os.unlink(journal_path(self.path))
        if end is not None and self.size() > end:
            with contextlib.suppress(OSError):
                os.ftruncate(self.fd, end)
        os.close(self.fd)

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
        return page

    def _keep(self, at: int, b: memoryview, only_kept: bool = False) -> None:
        """Copy ``b`` (to go at ``at``) into the pages kept in memory (``only_kept``: those already kept)."""
        end = at + len(b)
        for p in range(at // PAGE, (end - 1) // PAGE + 1):
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
    """Copy a whole journal's pages into the file ``fd`` (held locked), then remove the journal."""
    try:
        with open(where, "rb") as j:
            record = j.read()
    except FileNotFoundError:
        return False
    pages = _pages(record, os.fstat(fd))
    if pages:
        for p, page in pages:
            _pwrite_all(fd, page, p * PAGE)
        os.fsync(fd)
    with contextlib.suppress(FileNotFoundError):
        os.unlink(where)
    _sync_folder(where)
    return bool(pages)


def _pages(record: bytes, st: os.stat_result) -> list[tuple[int, bytes]]:
    """The pages of a whole journal of this file (by device and inode); none for a torn or foreign one."""
    if len(record) < HEADER.size + DIGEST:
        return []
    magic, dev, ino, count, _ = HEADER.unpack_from(record)
    size = HEADER.size + count * (8 + PAGE)
    if magic != MAGIC or (dev, ino) != (st.st_dev, st.st_ino) or len(record) < size + DIGEST:
        return []
    if hashlib.blake2b(record[:size], digest_size=DIGEST).digest() != record[size : size + DIGEST]:
        return []
    out = []
    for k in range(count):
        at = HEADER.size + k * (8 + PAGE)
        (p,) = struct.unpack_from("<Q", record, at)
        out.append((p, record[at + 8 : at + 8 + PAGE]))
    return out


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
