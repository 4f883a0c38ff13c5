"""What each HDF5 filter costs on the columns ``labcli import`` writes: time and bytes, gzip level and shuffle.

Run:  python tests/benchmarks/table_filters.py [--rows 200000] [--repeat 5] [--figures FILE.json]

A trial CSV of ``--rows`` rows (tests/benchmarks/bench_tables.py's table, interleaved split) is
imported once; its bulk columns are read back from the run file (P0, P, F, theta as float64,
the row checksums, the trial ids, the split's ids) and written again with bare h5py into an
in-memory file, chunked as the run file chunks them, under each way of filtering:

* ``gzip 4 shuffle`` (with Fletcher32): what every table column had before;
* ``gzip 1 shuffle`` (with Fletcher32);
* ``gzip 1`` (with Fletcher32, no shuffle): what a float column of a table has now;
* ``gzip 1 bare``: the import baseline's own filter (tests/benchmarks/baselines/import_h5py.py).

Per way and per kind of column (the float columns together, the whole-number columns together):
the CPU time of the writes (median of ``--repeat``) and the stored bytes over the raw bytes.
"""

from __future__ import annotations

import argparse
import io
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parents[1]))
sys.path.insert(0, str(HERE))

from fresh import machine, write_figures  # noqa: E402

WAYS = {
    "gzip 4 shuffle": {"compression": "gzip", "compression_opts": 4, "shuffle": True, "fletcher32": True},
    "gzip 1 shuffle": {"compression": "gzip", "compression_opts": 1, "shuffle": True, "fletcher32": True},
    "gzip 1": {"compression": "gzip", "compression_opts": 1, "fletcher32": True},
    "gzip 1 bare": {"compression": "gzip", "compression_opts": 1},
}
FLOATS = ("P0", "P", "F", "theta")
WHOLE = ("checksum", "trial")


def columns(rows: int, work: Path) -> dict[str, tuple[object, tuple[int, ...]]]:
    """The import's bulk columns and their chunk shapes, read back from a run file."""
    import h5py
    from bench_tables import write_table

    csv, h5 = work / "t.csv", work / "t.h5"
    write_table(rows, csv, "interleaved")
    subprocess.run(
        [sys.executable, "-m", "labcli", "import", str(csv), "-o", str(h5), "--protocol", "takuma2014", "--force"],
        check=True,
        stdout=subprocess.DEVNULL,
    )
    out: dict[str, tuple[object, tuple[int, ...]]] = {}
    with h5py.File(h5, "r") as f:
        for name in (*FLOATS, *WHOLE):
            ds = f["entry/trials"][name]
            out[name] = (ds[()], ds.chunks)
        ds = f["entry/split/ids"]
        out["split ids"] = (ds[()], ds.chunks)
    return out


def write(cols: dict, names: tuple[str, ...], filters: dict) -> tuple[float, int]:
    """CPU seconds to write ``names`` with ``filters``, and the bytes stored."""
    import h5py

    t = time.process_time()
    with h5py.File(io.BytesIO(), "w") as f:
        for name in names:
            data, chunks = cols[name]
            f.create_dataset(name, data=data, chunks=chunks, **filters)
        f.flush()
        stored = sum(f[name].id.get_storage_size() for name in names)
    return time.process_time() - t, stored


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=float, default=200_000, help="rows of the imported trial table")
    ap.add_argument("--repeat", type=int, default=5, help="rounds per figure (the median is kept)")
    ap.add_argument("--figures", default=None, help="write the figures to this JSON file ({name: value})")
    args = ap.parse_args()
    figures: dict = {**machine(), "rows": int(args.rows), "rounds per figure": args.repeat}
    with tempfile.TemporaryDirectory() as tmp:
        cols = columns(int(args.rows), Path(tmp))
    kinds = {"float": FLOATS, "whole": (*WHOLE, "split ids")}
    print(f"{int(args.rows)} rows, CPU of the writes (median of {args.repeat}) and stored / raw bytes")
    for kind, names in kinds.items():
        raw = sum(cols[n][0].nbytes for n in names)
        for way, filters in WAYS.items():
            runs = [write(cols, names, filters) for _ in range(args.repeat)]
            cpu = statistics.median(r[0] for r in runs)
            size = runs[0][1] / raw
            figures[f"{kind} columns {way} cpu s"] = round(cpu, 3)
            figures[f"{kind} columns {way} size ratio"] = round(size, 3)
            print(f"  {kind:5s} columns  {way:15s} {cpu:7.3f} s  {size:5.2f} of the raw bytes")
        old, new = figures[f"{kind} columns gzip 4 shuffle cpu s"], figures[f"{kind} columns gzip 1 cpu s"]
        figures[f"{kind} columns gzip 4 shuffle over gzip 1 cpu"] = round(old / new, 2)
        old, new = figures[f"{kind} columns gzip 4 shuffle size ratio"], figures[f"{kind} columns gzip 1 size ratio"]
        figures[f"{kind} columns gzip 4 shuffle over gzip 1 size"] = round(old / new, 2)
    if args.figures:
        write_figures(args.figures, figures)


if __name__ == "__main__":
    main()
