"""Random bit flips over a run file never give a traceback and never a silently changed value.

A flip is either detected (a LabcliError, or a LabcliWarning naming what is left out, and then
what is read is a part of what was written) or lands in bytes nothing reads.  Each campaign
runs in its own process (:mod:`support.bitflip`) so a crash inside HDF5 fails the test by name.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from collections import Counter
from pathlib import Path

import pytest
from support.records import FakeDevice, FakeProtocol, make_record

from labcli.core.store import RunFile

ROOT = Path(__file__).resolve().parents[2]
CHECKER = ROOT / "tests" / "support" / "bitflip.py"


def small_run(path: str) -> None:
    with RunFile.create(
        path,
        protocol=FakeProtocol(),
        device_info=FakeDevice(),
        port="sim://?seed=1",
        operator="ada",
        plan={"trial": [0, 1, 2, 3], "mass_g": [50.0, 100.0, 150.0, 200.0]},
    ) as run:
        for i in range(4):
            run.records.write({**make_record(i, 20), "flags": [f"Note {i} about this trial."]})
        run.split.set([0, 1, 2], [3], "sequential")
        run.models.record("takuma2014", '{"beta": [1.0, 2.0]}')


def campaign(tmp_path: Path, seed: int, flips: int) -> Counter:
    good = str(tmp_path / "good.h5")
    small_run(good)
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + str(ROOT / "tests"))
    p = subprocess.run(
        [sys.executable, str(CHECKER), good, str(tmp_path / "flipped.h5"), str(seed), str(flips)],
        capture_output=True,
        text=True,
        env=env,
        timeout=600,
    )
    lines = [json.loads(x) for x in p.stdout.splitlines()]
    assert p.returncode == 0 and len(lines) == flips, (p.returncode, p.stderr[-2000:], lines[-1:])
    bad = [x for x in lines if x["outcome"] in ("traceback", "changed")]
    assert not bad, bad[:3]
    return Counter(x["outcome"] for x in lines)


def test_random_bit_flips(tmp_path):
    outcomes = campaign(tmp_path, seed=1, flips=60)
    assert outcomes["detected"] > 0  # the campaign did hit bytes that are read


@pytest.mark.slow
def test_random_bit_flips_many(tmp_path):
    outcomes = campaign(tmp_path, seed=2, flips=1000)
    print(dict(outcomes))


def test_a_lost_chunk_record_is_damage_not_a_gap(tmp_path):
    # A flipped bit in the address of the models table's one checksum chunk (campaign seed 1, about
    # one file in three) left the chunk unrecorded: HDF5 then reads zeros, the mark of rows a commit
    # never wrote (a gap, skipped), and the model vanished without a word.
    import h5py
    import numpy as np

    from labcli.errors import LabcliWarning

    path = tmp_path / "run.h5"
    small_run(str(path))
    with h5py.File(path, "r") as f:
        at = f["entry/models/checksum"].id.get_chunk_info_by_coord((0,)).byte_offset
    data = bytearray(path.read_bytes())
    where = data.find(np.uint64(at).tobytes())
    assert where >= 0 and where != at  # the address, in the dataset's layout, not the chunk itself
    data[where : where + 8] = b"\xff" * 8  # HDF5's undefined address: no chunk recorded
    path.write_bytes(bytes(data))
    with h5py.File(path, "r") as f:
        assert f["entry/models/checksum"].id.get_chunk_info_by_coord((0,)).byte_offset is None
        assert f["entry/models/checksum"][0] == 0
    with pytest.warns(LabcliWarning, match="model row 0: its checksum does not match its values; it is left out"):
        with RunFile.open(str(path)) as run:
            assert run.models.all() == {}
    with RunFile.open(str(path)) as run:
        assert run.verify()["ok"] is False
