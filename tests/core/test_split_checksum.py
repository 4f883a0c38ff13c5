"""A split's ids checksummed whole-array (version 2), and the word-by-word fold older files keep (version 1).

A new run file's split log says which checksum each split's ids carry (``ids_checksum_version``);
a log written before that column existed holds version 1, which is still checked, and a new split
committed to such a file is checksummed as its readers expect.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest

from labcli.core.store import RunFile, import_table
from labcli.core.store.blobs import blob_checksum, blob_read
from labcli.core.store.checksum import _BASIS, _PRIME, _STEP, words_checksum
from labcli.errors import LabcliWarning

DATA = Path(__file__).resolve().parents[1] / "data"
MASK = (1 << 64) - 1


def reference(ids: np.ndarray) -> int:
    """Version 2 spelt out: each little-endian word folded from its place's start, summed mod 2**64."""
    total = 0
    for i, w in enumerate(ids.astype("<i8").view("<u8").tolist()):
        start = int(_BASIS) ^ ((i * int(_STEP)) & MASK)
        total = (total + ((start ^ w) * int(_PRIME) & MASK)) & MASK
    return total


def test_version_2_is_the_sum_of_each_words_fold_and_changes_with_any_one_bit_or_a_swap():
    rng = np.random.default_rng(3)
    ids = rng.permutation(5000).astype(np.int64)
    h = words_checksum(ids)
    assert h == reference(ids)
    for pos, bit in zip(rng.integers(0, len(ids), 40), rng.integers(0, 64, 40), strict=True):
        flipped = ids.copy()
        flipped.view(np.uint64)[pos] ^= np.uint64(1 << int(bit))
        assert words_checksum(flipped) != h
    swapped = ids.copy()
    swapped[[10, 4000]] = swapped[[4000, 10]]
    assert words_checksum(swapped) != h
    assert words_checksum(np.frombuffer(b"abc", dtype=np.uint8)) == reference(
        np.frombuffer(b"abc".ljust(8, b"\0"), dtype="<i8")
    )  # a piece of bytes: its last word padded with zeros


def flip_id(path: Path, k: int) -> None:
    """One bit of the k-th id stored in the split blob, changed (HDF5's own chunk checksum made anew)."""
    with h5py.File(path, "r+") as f:
        ds = f["entry/split/ids"]
        ds[k] = int(ds[k]) ^ 4


def imported(path: Path, n: int = 300) -> tuple[list[int], list[int]]:
    import pandas as pd

    from labcli.core.protocol import load_protocol

    rng = np.random.default_rng(5)
    df = pd.DataFrame({"trial": np.arange(n) + 1, "set": np.where(np.arange(n) % 6 == 5, "validation", "fit")})
    for c in ("P_L10", "P_R10", "P_L20", "P_R20"):
        df[c] = np.round(0.2 + 0.01 * rng.standard_normal(n), 6)
    for c in ("P_L1", "P_R1", "P_L2", "P_R2"):
        df[c] = np.round(0.25 + 0.02 * rng.standard_normal(n), 6)
    for c in ("theta1_deg", "theta2_deg", "Fx_N", "Fy_N"):
        df[c] = np.round(rng.uniform(-5, 5, n), 6)
    import_table(df, path, protocol=load_protocol("takuma2014")).close()
    return df.trial[df.set == "fit"].tolist(), df.trial[df.set == "validation"].tolist()


def test_a_new_files_split_carries_version_2_and_a_flipped_id_is_caught(tmp_path):
    path = tmp_path / "t.h5"
    fit, val = imported(path)
    with h5py.File(path, "r") as f:
        s = f["entry/split"]
        assert int(s["ids_checksum_version"][0]) == 2
        assert int(s["ids_checksum"][0]) == words_checksum(np.asarray(fit + val, dtype=np.int64))
    with RunFile.open(str(path)) as run:
        assert run.split.get()["fit"] == fit and run.split.get()["validation"] == val
    flip_id(path, 7)
    with RunFile.open(str(path)) as run, pytest.warns(LabcliWarning, match="ids of split 1 do not match"):
        assert run.split.get() is None


def test_an_older_files_split_is_checked_by_its_word_by_word_fold_and_takes_new_splits_so(tmp_path):
    path = tmp_path / "old.h5"
    shutil.copy(DATA / "v3" / "force-before-marks.h5", path)
    with h5py.File(path, "r") as f:
        assert "ids_checksum_version" not in f["entry/split"]
        stored = f["entry/split/ids"][:]
        assert int(f["entry/split/ids_checksum"][0]) == blob_checksum(stored, 1) != words_checksum(stored)
    with RunFile.open(str(path)) as run:
        old = run.split.get()
    assert old is not None and len(old["fit"]) + len(old["validation"]) == len(stored)
    with RunFile.open(str(path), mode="a") as run:
        run.split.set(old["fit"][:50], old["validation"][:10], "manual")
    with h5py.File(path, "r") as f:
        s = f["entry/split"]
        a, b = int(s["fit_start"][1]), int(s["validation_stop"][1])
        assert int(s["ids_checksum"][1]) == blob_checksum(s["ids"][a:b], 1)  # as its readers check it
    with RunFile.open(str(path)) as run:
        assert run.split.get()["fit"] == old["fit"][:50]
    flip_id(path, a + 3)  # the new split's ids: the old one, still whole, is in force again
    with RunFile.open(str(path)) as run, pytest.warns(LabcliWarning, match="ids of split 2 do not match"):
        assert run.split.get() == old


def test_ids_read_with_a_checksum_version_no_labcli_wrote_are_not_believed(tmp_path):
    path = tmp_path / "t.h5"
    fit, val = imported(path)
    with h5py.File(path, "r") as f:
        s = f["entry/split"]
        a, b, h = int(s["fit_start"][0]), int(s["validation_stop"][0]), int(s["ids_checksum"][0])
        assert blob_read(s, "ids", a, b, h, 2).tolist() == fit + val
        assert blob_read(s, "ids", a, b, h, 1) is None and blob_read(s, "ids", a, b, h, 3) is None
    with pytest.raises(ValueError, match="no blob checksum has version 3"):
        blob_checksum(np.arange(3), 3)
