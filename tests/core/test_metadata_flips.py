"""Single bit flips in a run file's metadata (tests/benchmarks/metadata_flips.py): ``inspect --verify``
refuses the file, or inspect, export, fit, validate and read_run all read it, never a traceback.

The campaign's short variant runs here (a few dozen cases spread over every region of the map);
the full one (``--cases 3000``: about a second of CPU a case, so most of an hour on two shared
cores) is marked slow.
"""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
import warnings
from pathlib import Path

import pytest
from support import procs

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "tests" / "benchmarks" / "metadata_flips.py"


def script():
    spec = importlib.util.spec_from_file_location("metadata_flips", SCRIPT)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def run_campaign(tmp_path: Path, *args: str) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), str(ROOT / "tests")]))
    return subprocess.run(
        [sys.executable, str(SCRIPT), "--dir", str(tmp_path), *args],
        capture_output=True,
        text=True,
        env=env,
        timeout=900,
    )


def test_the_map_names_the_metadata_and_leaves_out_the_datasets_values(tmp_path):
    m = script()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        run, model = m.record_run(tmp_path)
        meta = m.metadata_map(str(run), str(model))
    regions = {r for _, r in meta}
    for want in ("superblock", "header:attribute", "header:datatype", "header:layout", "B-tree", "local heap"):
        assert want in regions
    offsets = {o for o, _ in meta}
    assert set(range(48)) <= offsets  # the superblock (version 2) is read first, by everyone
    for a, b in m.data_ranges(str(run)):
        assert not offsets & set(range(a, b))  # raw frames and rows: their own checksums guard them
    cases, strides = m.pick(meta, 300)
    assert {c["region"] for c in cases} == regions and all(k % 2 for k in strides.values())
    assert {c["bit"] for c in cases} == set(range(8))


def test_a_short_campaign_finds_no_reader_failing_on_a_file_verify_passes(tmp_path):
    r = run_campaign(tmp_path, "--cases", "3000", "--limit", "16", "--workers", "1")
    assert r.returncode == 0 and "0 findings." in r.stdout, r.stdout[-3000:] + r.stderr[-2000:]
    assert r.stdout.startswith("16 cases (of 16 planned) over ")


def flip_in_header(path: Path, dataset: str, message: int, byte: int, bit: int) -> None:
    """Flip one bit of a message of ``dataset``'s object header (``byte`` counted from the message's prefix)."""
    import h5py

    m = script()
    with h5py.File(path, "r") as f:
        addr = h5py.h5o.get_info(f[dataset].id).addr
    blob = bytearray(path.read_bytes())
    at = next(at for kind, at, _ in m.messages(bytes(blob), addr) if kind == message)
    blob[at + byte] ^= 1 << bit
    path.write_bytes(bytes(blob))


def test_a_calibration_hdf5_cannot_read_fails_verify_and_is_one_sentence_to_every_reader(tmp_path):
    """Found by the campaign: one bit of the dataspace in the header of a channel's gain
    (entry/raw/calibration/POT2/gain) makes it hold no value: its attributes all check out, so
    verify passed (or, reading it, gave up on the whole file), and fit and validate, which read
    the calibration, traced back (IndexError)."""
    m = script()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        run, model = m.record_run(tmp_path)
    flip_in_header(run, "entry/raw/calibration/POT2/gain", 0x0001, 16, 0)  # its size: 1 -> 0
    r = procs.labcli("inspect", "--verify", run.name, cwd=tmp_path)
    assert r.returncode == 1 and "Traceback" not in r.stderr
    assert r.stdout == (
        f"damaged: calibration: {run.name}: its calibration cannot be read (damaged); check the file with "
        "labcli inspect --verify and use a backup copy.\n"
    )
    assert r.stderr == f"Error: {run.name}: 1 damaged item found; 12 trials and 24 raw windows check out.\n"
    for args in (("fit", run.name, "-o", "m.json"), ("validate", run.name, "--model", model.name)):
        r = procs.labcli(*args, cwd=tmp_path)
        assert r.returncode == 1 and r.stderr == (
            f"Error: {run.name}: its calibration cannot be read (damaged); check the file with labcli "
            "inspect --verify and use a backup copy.\n"
        )
    assert not (tmp_path / "m.json").exists()


@pytest.mark.slow
def test_the_full_campaign(tmp_path):
    r = run_campaign(tmp_path, "--cases", "3000", "--workers", "2")
    print(r.stdout)
    assert r.returncode == 0 and "0 findings." in r.stdout, r.stdout[-3000:] + r.stderr[-2000:]
