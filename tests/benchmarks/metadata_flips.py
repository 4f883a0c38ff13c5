"""Single bit flips in a run file's metadata: ``inspect --verify`` refuses the file, or every reader reads it.

Run:  nice -n 10 python tests/benchmarks/metadata_flips.py [--cases 3000] [--limit N] [--workers 2]
                                                           [--run RUN.h5] [--out flips.jsonl] [--dir D]
                                                           [--replay flips.jsonl] [--minutes M]
                                                           [--realism kind] [--seeds 1]

A run is recorded (``labcli acquire`` on ``sim://?seed=1&clock=virtual&realism=kind``, 12 trials: 9 fit, 3
validation; ``--seeds``, ``--realism``: rig_options.py), or ``--run`` names one (a sample run's
copy).  Its metadata are mapped: the bytes
HDF5 reads while ``inspect --verify``, ``inspect``, ``export``, ``fit``, ``validate`` and
``labcli.read_run`` read the run, less the bytes of its datasets' chunks (raw frames and table
rows, which their own checksums guard), each byte named by the structure it lies in:
``superblock``, an object header's message (``header:attribute``, ``header:layout``,
``header:datatype``, ... and ``header:prefix``), a ``B-tree`` node, a ``local heap``, a
``symbol table node``, a ``global heap`` (variable-length strings) or ``other``.  Each region
gets an equal share of the cases: every ``K``-th of its bits is flipped (K odd, so every bit
position of a byte is hit; every bit of a small region), one flip per case on a fresh copy, and
each case runs, in-process through the command line's own entry points:

* ``inspect --verify`` (its exit code), then every reader: ``inspect``, ``export -o``,
  ``fit --form paper -o`` (the run file untouched; the paper's form reads the run as the posture
  form does, in a fifth of the time), ``validate --model`` (the good run's posture model) and
  ``labcli.read_run``.

A case is a *finding* when a reader traces back (an exception that is not the command's own
sentence), when verify exits 0 and a reader refuses the file or its export differs from the good
run's (a silent change), or when the case crashes the process or hangs (each case runs in a
worker process, restarted after a crash).  The report counts the cases, the bits and bytes they
cover per region, and lists every finding; the exit code is 1 when there is one.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import random
import shutil
import struct
import subprocess
import sys
import tempfile
import threading
import time
import traceback
import warnings
from collections import Counter
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
SIM = "sim://?seed={seed}&clock=virtual&realism={realism}"
HANG_S = 120.0  # a case still running after this long is a hang
# fit as the campaign runs it: the paper's form reads the run as the posture form does, in a fifth of
# the time; 12 trials put some near theta2 = 0, where its default cut (100) refuses them
FIT = ("--form", "paper", "--max-amplification", "1000")
MESSAGES = {
    0x0000: "nil",
    0x0001: "dataspace",
    0x0003: "datatype",
    0x0004: "fill value (old)",
    0x0005: "fill value",
    0x0008: "layout",
    0x000B: "filter pipeline",
    0x000C: "attribute",
    0x0010: "continuation",
    0x0011: "symbol table",
    0x0012: "modification time",
}
SIGNATURES = {b"TREE": "B-tree", b"HEAP": "local heap", b"SNOD": "symbol table node", b"GCOL": "global heap"}


def plan_csv(path: Path) -> None:
    rows = ["trial,set,mass_g,direction_deg"]
    for i in range(1, 13):
        rows.append(f"{i},{'fit' if i <= 9 else 'validation'},{200 + 50 * i},{(i * 30) % 360 - 180}")
    path.write_text("\n".join(rows) + "\n")


def invoke(args: list[str]) -> tuple[str, str]:
    """One command in-process: ("ok", ""), ("refused", its sentence), ("hdf5", what h5py raised: the
    command line's last resort says a run file is damaged) or ("traceback", the traceback)."""
    from click.testing import CliRunner

    from labcli.cli import _from_hdf5, cli

    r = CliRunner().invoke(cli, args, catch_exceptions=True)
    if r.exception is None or (isinstance(r.exception, SystemExit) and r.exit_code == 0):
        return "ok", ""
    if isinstance(r.exception, SystemExit):
        return "refused", (r.stderr if hasattr(r, "stderr") else r.output).strip()[-300:]
    e = r.exception
    kind = "hdf5" if isinstance(e, (OSError, RuntimeError, KeyError)) and _from_hdf5(e) else "traceback"
    return kind, "".join(traceback.format_exception(type(e), e, e.__traceback__, limit=-4))[-600:]


def library(path: str) -> tuple[str, str]:
    """``labcli.read_run``: ("ok", ""), ("refused", a LabcliError's sentence) or ("traceback", ...)."""
    import labcli
    from labcli.errors import LabcliError

    try:
        labcli.read_run(path)
    except LabcliError as e:
        return "refused", str(e)[-300:]
    except Exception as e:  # noqa: BLE001 - what the campaign counts as a traceback
        return "traceback", "".join(traceback.format_exception(type(e), e, e.__traceback__, limit=-4))[-600:]
    return "ok", ""


def check(work: Path, model: Path) -> dict[str, Any]:
    """verify, then every reader, on the run file at ``work``."""
    d = work.parent
    for leftover in ("out.csv", "out.model.json"):
        with contextlib.suppress(FileNotFoundError):
            (d / leftover).unlink()
    verify = invoke(["inspect", "--verify", str(work)])
    readers = {
        "inspect": invoke(["inspect", str(work)]),
        "export": invoke(["export", str(work), "-o", str(d / "out.csv")]),
        "fit": invoke(["fit", str(work), *FIT, "-o", str(d / "out.model.json")]),
        "validate": invoke(["validate", str(work), "--model", str(model)]),
        "read_run": library(str(work)),
    }
    exported = (d / "out.csv").read_bytes() if (d / "out.csv").exists() else None
    return {"verify": verify, "readers": readers, "export": exported}


def judge(got: dict[str, Any], good_export: bytes | None) -> list[str]:
    """What is wrong with a case: empty when verify refused it or every reader read it whole."""
    out = []
    passed = got["verify"][0] == "ok"
    if got["verify"][0] == "traceback":
        out.append("verify traces back")
    for name, (kind, _) in got["readers"].items():
        if kind == "traceback":
            out.append(f"{name} traces back")
        elif passed and kind != "ok":
            out.append(f"verify passes, {name} {'fails in HDF5' if kind == 'hdf5' else 'refuses'}")
    if passed and got["readers"]["export"][0] == "ok" and got["export"] != good_export:
        out.append("verify passes, export differs (a silent change)")
    return out


# ----------------------------------------------------------------- the map of the metadata


class LoggedReads(io.RawIOBase):
    """A file HDF5 reads through h5py's file-object driver, every range it reads noted."""

    def __init__(self, path: str, ranges: list[tuple[int, int]]) -> None:
        self._f = open(path, "rb")  # noqa: SIM115 - closed with this object
        self._ranges = ranges

    def readable(self) -> bool:
        return True

    def seekable(self) -> bool:
        return True

    def seek(self, pos: int, whence: int = 0) -> int:
        return self._f.seek(pos, whence)

    def tell(self) -> int:
        return self._f.tell()

    def readinto(self, b: Any) -> int:
        at = self._f.tell()
        n = self._f.readinto(b)
        self._ranges.append((at, at + (n or 0)))
        return n or 0

    def close(self) -> None:
        self._f.close()
        super().close()


@contextlib.contextmanager
def reads_of(path: str):
    """The byte ranges HDF5 reads of ``path`` while the block runs (every h5py.File of it logged)."""
    import h5py

    ranges: list[tuple[int, int]] = []
    real = h5py.File
    target = os.path.realpath(path)

    class Logged(real):  # type: ignore[misc,valid-type]
        def __init__(self, name: Any, mode: str = "r", *a: Any, **kw: Any) -> None:
            if isinstance(name, (str, os.PathLike)) and mode == "r" and os.path.realpath(name) == target:
                kw.pop("locking", None)
                name = LoggedReads(target, ranges)
            super().__init__(name, mode, *a, **kw)

    h5py.File = Logged
    try:
        yield ranges
    finally:
        h5py.File = real


def data_ranges(path: str) -> list[tuple[int, int]]:
    """The byte ranges of every dataset's stored values (chunks, or a contiguous block)."""
    import h5py

    out: list[tuple[int, int]] = []

    def visit(_name: str, obj: Any) -> None:
        if not isinstance(obj, h5py.Dataset):
            return
        layout = obj.id.get_create_plist().get_layout()
        if layout == h5py.h5d.CHUNKED:
            for i in range(obj.id.get_num_chunks()):
                c = obj.id.get_chunk_info(i)
                out.append((c.byte_offset, c.byte_offset + c.size))
        elif layout == h5py.h5d.CONTIGUOUS and obj.id.get_offset() is not None:
            out.append((obj.id.get_offset(), obj.id.get_offset() + obj.id.get_storage_size()))

    with h5py.File(path, "r") as f:
        f.visititems(visit)
    return out


def messages(blob: bytes, addr: int) -> list[tuple[int, int, int]]:
    """The messages of the version-1 object header at ``addr``: (type, offset of its 8-byte prefix, size)."""
    (size,) = struct.unpack_from("<I", blob, addr + 8)
    out, blocks = [], [(addr + 16, size)]
    while blocks:
        at, length = blocks.pop()
        end = min(at + length, len(blob))
        while at + 8 <= end:
            kind, n = struct.unpack_from("<HH", blob, at)
            out.append((kind, at, n))
            if kind == 0x0010 and n >= 16:
                blocks.append(struct.unpack_from("<QQ", blob, at + 8))
            at += 8 + n
    return out


def header_regions(path: str) -> dict[int, str]:
    """Each byte of every object header (version 1, as the run files' 'earliest' format writes
    them), named by the message it lies in; the superblock's bytes too."""
    import h5py

    blob = Path(path).read_bytes()
    names: dict[int, str] = {}
    version = blob[8]  # 0 and 1: the root group's symbol table entry inside; 2 and 3: a checksum
    names.update({i: "superblock" for i in range({0: 96, 1: 100}.get(version, 48))})
    addrs = set()
    if version >= 2:  # its extension (the file space settings) is an object header of its own
        (extension,) = struct.unpack_from("<Q", blob, 20)
        if extension < len(blob):
            addrs.add(extension)
    with h5py.File(path, "r") as f:
        addrs.add(h5py.h5o.get_info(f.id).addr)
        f.visititems(lambda _n, obj: addrs.add(h5py.h5o.get_info(obj.id).addr) and None)
    for addr in addrs:
        if blob[addr] != 1:
            continue  # not a version-1 header: left to the signatures
        names.update({i: "header:prefix" for i in range(addr, addr + 16)})
        for kind, at, n in messages(blob, addr):
            label = "header:" + MESSAGES.get(kind, f"message {kind:#06x}")
            names.update({i: label for i in range(at, min(at + 8 + n, len(blob)))})
    return names


def metadata_map(path: str, model: str) -> list[tuple[int, str]]:
    """(offset, region) of every byte of metadata the readers read, in file order."""
    with reads_of(path) as ranges, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        check(Path(path), Path(model))
    blob = Path(path).read_bytes()
    read = bytearray(len(blob))
    for a, b in ranges:
        read[a:b] = b"\x01" * (min(b, len(blob)) - a)
    for a, b in data_ranges(path):
        read[a:b] = b"\x00" * (b - a)
    names = header_regions(path)
    signed: dict[int, str] = {}
    for a, b in sorted(set(ranges)):
        label = SIGNATURES.get(blob[a : a + 4])
        if label:
            signed.update({i: label for i in range(a, min(b, len(blob)))})
    return [(i, names.get(i) or signed.get(i) or "other") for i in range(len(blob)) if read[i]]


# ----------------------------------------------------------------- the campaign


def record_run(d: Path, seed: int = 1, realism: str = "kind") -> tuple[Path, Path]:
    """A 12-trial run recorded on the simulated rig, and its model (fit in the posture form)."""
    plan_csv(d / "plan12.csv")
    run, model = d / "good.h5", d / "good.model.json"
    port = SIM.format(seed=seed, realism=realism)
    for args in (
        ["acquire", str(run), "--port", port, "--unattended", "--plan", str(d / "plan12.csv")],
        ["fit", str(run), "-o", str(model)],
    ):
        kind, detail = invoke(args)
        if kind != "ok":
            raise SystemExit(f"could not prepare the run: {' '.join(args)}: {detail}")
    return run, model


def worker(spec: Path) -> None:
    """Run the cases listed in ``spec`` (JSON), one JSON line each, in order."""
    s = json.loads(spec.read_text())
    good, model, d = Path(s["good"]), Path(s["model"]), Path(s["dir"])
    work = d / "run.h5"
    warnings.simplefilter("ignore")
    for case in s["cases"]:
        if time.time() > s["deadline"]:
            return  # the campaign's time is up: the cases left are not run
        shutil.copyfile(good, work)
        with open(work, "r+b") as fh:
            fh.seek(case["offset"])
            byte = fh.read(1)[0]
            fh.seek(case["offset"])
            fh.write(bytes([byte ^ (1 << case["bit"])]))
        t0 = time.perf_counter()
        got = check(work, model)
        row = {
            **case,
            "verify": got["verify"][0],
            "readers": {k: v[0] for k, v in got["readers"].items()},
            "findings": judge(got, s["good_export"].encode("latin-1") if s["good_export"] is not None else None),
            "seconds": round(time.perf_counter() - t0, 3),
        }
        if row["findings"]:
            row["detail"] = {k: v[1] for k, v in [("verify", got["verify"]), *got["readers"].items()] if v[1]}
        print(json.dumps(row), flush=True)


def run_slot(cases: list[dict], base: dict, d: Path, out: list[dict], lock: threading.Lock, log: Path | None) -> None:
    """Run ``cases`` in worker processes one after another: a crash or a hang is that case's row."""
    todo = list(cases)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), str(ROOT / "tests")]))
    while todo:
        spec = d / "spec.json"
        spec.write_text(json.dumps({**base, "dir": str(d), "cases": todo}))
        proc = subprocess.Popen(
            [sys.executable, __file__, "--worker", str(spec)],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env=env,
            cwd=d,
        )
        assert proc.stdout is not None
        done = 0
        timer = threading.Timer(HANG_S, proc.kill)
        timer.start()
        for line in proc.stdout:
            timer.cancel()
            row = json.loads(line)
            with lock:
                out.append(row)
                if log is not None:  # as they come: a long campaign shows its progress
                    with open(log, "a") as fh:
                        fh.write(line)
            done += 1
            timer = threading.Timer(HANG_S, proc.kill)
            timer.start()
        timer.cancel()
        proc.wait()
        err = proc.stderr.read() if proc.stderr is not None else ""
        todo = todo[done:]
        if todo and proc.returncode == 0 and time.time() > base["deadline"]:
            return  # stopped at the deadline, between two cases
        if todo:  # the case under way crashed the worker, or hung and was killed
            case = todo.pop(0)
            what = f"crash (signal {-proc.returncode})" if proc.returncode < 0 else f"exit {proc.returncode}"
            row = {**case, "verify": "?", "readers": {}, "findings": [what], "detail": {"stderr": err[-600:]}}
            with lock:
                out.append(row)
                if log is not None:
                    with open(log, "a") as fh:
                        fh.write(json.dumps(row) + "\n")


def pick(meta: list[tuple[int, str]], cases: int) -> tuple[list[dict], dict[str, int]]:
    """The cases: an equal share of ``cases`` for every region, every K-th bit of its own (K odd, so
    every bit position of a byte is hit; every bit of a region smaller than its share); and each
    region's K."""
    by_region: dict[str, list[int]] = {}
    for offset, region in meta:
        by_region.setdefault(region, []).append(offset)
    share = max(1, cases // max(1, len(by_region)))
    out, strides = [], {}
    for region, offsets in sorted(by_region.items()):
        bits = 8 * len(offsets)
        k = max(1, bits // share)
        k += k % 2 == 0
        strides[region] = k
        out += [{"offset": offsets[b // 8], "bit": b % 8, "region": region} for b in range(k // 2, bits, k)]
    return sorted(out, key=lambda c: (c["offset"], c["bit"])), strides


def campaign(
    run: Path,
    model: Path,
    meta: list[tuple[int, str]],
    d: Path,
    cases: int,
    workers: int,
    limit: int | None,
    log: Path | None = None,
    replay: Path | None = None,
    minutes: float = float("inf"),
) -> dict[str, Any]:
    """Flip the bits :func:`pick` chooses of the metadata map ``meta``; the rows, the map's size and the findings."""
    todo, strides = pick(meta, cases)
    if replay is not None:  # the cases of an earlier campaign's --out that found something, again
        rows = [json.loads(x) for x in replay.read_text().splitlines() if x.strip()]
        todo = [{k: r[k] for k in ("offset", "bit", "region")} for r in rows if r["findings"]]
    if limit is not None:
        todo = todo[:: max(1, len(todo) // limit)][:limit]
    random.Random(1).shuffle(todo)  # cut short by --minutes, the cases run are still spread over the file
    shutil.copyfile(run, d / "run.h5")
    good = check(d / "run.h5", model)
    if good["verify"][0] != "ok" or any(v[0] != "ok" for v in good["readers"].values()):
        raise SystemExit(f"the unflipped run does not read cleanly: {good['verify']} {good['readers']}")
    base = {
        "deadline": time.time() + 60 * minutes,
        "good": str(run),
        "model": str(model),
        "good_export": good["export"].decode("latin-1") if good["export"] is not None else None,
    }
    rows: list[dict] = []
    lock = threading.Lock()
    slots = []
    for w in range(workers):
        wd = d / f"w{w}"
        wd.mkdir(exist_ok=True)
        t = threading.Thread(target=run_slot, args=(todo[w::workers], base, wd, rows, lock, log))
        t.start()
        slots.append(t)
    for t in slots:
        t.join()
    regions = Counter(r for _, r in meta)
    rows.sort(key=lambda r: (r["offset"], r["bit"]))
    return {"rows": rows, "bytes": regions, "bits": 8 * len(meta), "strides": strides, "planned": len(todo)}


def report(res: dict[str, Any], seconds: float) -> str:
    rows = res["rows"]
    by_region: dict[str, Counter] = {}
    for r in rows:
        c = by_region.setdefault(r["region"], Counter())
        c["cases"] += 1
        c["verify refuses" if r["verify"] not in ("ok", "?") else "verify passes"] += 1
        c["findings"] += bool(r["findings"])
    lines = [
        f"{len(rows)} cases (of {res['planned']} planned) over {res['bits']} metadata bits ({sum(res['bytes'].values())} bytes the readers "
        f"read, less the datasets' chunks), in {seconds:.0f} s",
        "",
        "| region | bytes | every K-th bit | cases | verify refuses | verify passes | findings |",
        "|---|---|---|---|---|---|---|",
    ]
    for region, n in sorted(res["bytes"].items(), key=lambda kv: -kv[1]):
        c = by_region.get(region, Counter())
        lines.append(
            f"| {region} | {n} | {res['strides'][region]} | {c['cases']} | {c['verify refuses']} "
            f"| {c['verify passes']} | {c['findings']} |"
        )
    found = [r for r in rows if r["findings"]]
    lines += ["", f"{len(found)} findings" + (":" if found else ".")]
    for r in found:
        lines.append(f"- offset {r['offset']} bit {r['bit']} ({r['region']}): {'; '.join(r['findings'])}")
        for k, v in (r.get("detail") or {}).items():
            lines.append(f"    {k}: {v.strip().splitlines()[-1] if v.strip() else ''}")
    return "\n".join(lines)


def main() -> int:
    sys.path.insert(0, str(Path(__file__).resolve().parent))  # the tests load this file by its path
    from rig_options import add_rig_options, bench_parser

    p = bench_parser(__doc__)
    p.add_argument("--worker", type=Path, help=argparse.SUPPRESS)
    p.add_argument("--run", type=Path, help="a run file to flip (default: a 12-trial run recorded now)")
    p.add_argument("--cases", type=int, default=3000, help="about this many cases, shared equally by the regions")
    p.add_argument("--limit", type=int, help="run only N of them, spread evenly (a quick check)")
    p.add_argument("--replay", type=Path, help="run again only the cases of an --out file that found something")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--minutes", type=float, default=float("inf"), help="start no case after this long")
    p.add_argument("--out", type=Path, help="every case as a JSON line (as they come, then in file order)")
    p.add_argument("--dir", type=Path, help="work here (default: a temporary folder)")
    add_rig_options(p, realism="kind", seeds="1", one=True)  # the recorded run's rig
    a = p.parse_args()
    if a.worker:
        worker(a.worker)
        return 0
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="metaflips-", dir=a.dir) as tmp:
        d = Path(tmp)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            if a.run:
                run, model = d / "good.h5", d / "good.model.json"
                shutil.copyfile(a.run, run)
                kind, detail = invoke(["fit", str(run), "-o", str(model)])
                if kind != "ok":
                    raise SystemExit(f"could not fit {a.run}: {detail}")
            else:
                run, model = record_run(d, a.seeds[0], a.realism)
            shutil.copyfile(run, d / "map.h5")
            meta = metadata_map(str(d / "map.h5"), str(model))
        if a.out:
            a.out.write_text("")
        res = campaign(run, model, meta, d, a.cases, a.workers, a.limit, a.out, a.replay, a.minutes)
    if a.out:
        a.out.write_text("".join(json.dumps(r) + "\n" for r in res["rows"]))
    print(report(res, time.perf_counter() - t0))
    return 1 if any(r["findings"] for r in res["rows"]) else 0


if __name__ == "__main__":
    sys.exit(main())
