"""A bulk import writes what its table gives, checks it as before, and syncs its file once.

``labcli import`` of an archive builds its run file under a temporary name: the rows go in as
one commit, columns the table leaves at their fill value (no masses, no directions, no rest
posture) are left unwritten, the split it commits is the split in force without its ids being
read back, and the file is synced once, whole, just before it is put in place.
"""

from __future__ import annotations

import os
from pathlib import Path

import h5py
import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from labcli.cli import cli
from labcli.core.paper import Column
from labcli.core.protocol import load_protocol
from labcli.core.store import RunFile, import_csv
from labcli.core.store.checksum import row_checksums
from labcli.core.store.columns import Table, all_fill
from labcli.errors import StoreError

BASELINE = ["P_L10", "P_R10", "P_L20", "P_R20"]
LOADED = ["P_L1", "P_R1", "P_L2", "P_R2"]


def trial_csv(path: Path, n: int, seed: int = 4) -> pd.DataFrame:
    """n trials without masses, directions or rest posture; every sixth in the validation set."""
    rng = np.random.default_rng(seed)
    df = pd.DataFrame({"trial": np.arange(n) * 3 + 1})
    df["set"] = np.where(np.arange(n) % 6 == 5, "validation", "fit")
    for c in BASELINE:
        df[c] = np.round(0.2 + 0.01 * rng.standard_normal(n), 6)
    for c in LOADED:
        df[c] = np.round(0.25 + 0.02 * rng.standard_normal(n), 6)
    df["theta1_deg"] = np.round(rng.uniform(-20, 20, n), 4)
    df["theta2_deg"] = np.round(rng.uniform(-20, 20, n), 4)
    df["Fx_N"] = np.round(rng.uniform(-2, 2, n), 5)
    df["Fy_N"] = np.round(rng.uniform(-2, 2, n), 5)
    df.to_csv(path, index=False)
    return df


def test_an_import_leaves_columns_given_as_fill_unwritten_and_reads_and_exports_them_back(tmp_path):
    src = tmp_path / "t.csv"
    df = trial_csv(src, 1500)
    out = tmp_path / "t.h5"
    imported = import_csv(str(src), str(out), protocol="takuma2014")
    assert imported.n == 1500
    with h5py.File(out, "r") as f:
        rows = f["entry/trials"]
        for name in ("mass", "direction", "pot0"):
            assert rows[name].shape[0] >= 1500 and rows[name].id.get_storage_size() == 0, name
        for name in ("P", "P0", "theta", "F", "trial", "ended", "accepted"):
            assert rows[name].id.get_storage_size() > 0, name
    with RunFile.open(str(out)) as run:
        assert run.verify()["ok"] is True
        cols = run.records.columns().cols
        assert np.isnan(cols["mass"]).all() and np.isnan(cols["direction"]).all() and np.isnan(cols["pot0"]).all()
        np.testing.assert_array_equal(cols["trial"], df["trial"].to_numpy())
        np.testing.assert_array_equal(cols["P"], df[LOADED].to_numpy())
        split = run.split.get()
    assert split["fit"] == df.trial[df.set == "fit"].tolist()
    assert split["validation"] == df.trial[df.set == "validation"].tolist()
    back = tmp_path / "back.csv"
    res = CliRunner().invoke(cli, ["export", str(out), "-o", str(back)])
    assert res.exit_code == 0, res.output
    pd.testing.assert_frame_equal(pd.read_csv(back), pd.read_csv(src))  # no mass, direction or rest columns


def test_rest_postures_are_stored_in_radians_where_rows_give_them_and_not_at_all_when_none_does(tmp_path):
    src = tmp_path / "t.csv"
    df = trial_csv(src, 600)
    df["theta1_0_deg"], df["theta2_0_deg"] = np.nan, np.nan
    df.to_csv(src, index=False)  # the columns there, every cell empty
    import_csv(str(src), str(tmp_path / "none.h5"), protocol="takuma2014")
    with h5py.File(tmp_path / "none.h5", "r") as f:
        assert f["entry/trials/pot0"].id.get_storage_size() == 0
    df.loc[::3, "theta1_0_deg"] = 12.5
    df.loc[::3, "theta2_0_deg"] = -30.0  # on every third row (a table gives both or neither)
    df.to_csv(src, index=False)
    import_csv(str(src), str(tmp_path / "some.h5"), protocol="takuma2014")
    with RunFile.open(str(tmp_path / "some.h5")) as run:
        pot0 = run.records.columns().cols["pot0"]
    both = (np.arange(600) % 3) == 0
    np.testing.assert_allclose(pot0[both], np.radians([[12.5, -30.0]] * int(both.sum())), rtol=1e-15)
    assert np.isnan(pot0[~both]).all()


def test_unwritten_fill_rows_check_exactly_as_the_fill_spelt_out():
    # The checksum a row keeps is the same whether a column of fill is written or left unwritten:
    # what a reader folds from the fill it reads back.
    cols = [Column("a", "1", kind="float", shape=(2,)), Column("b", "1", kind="int"), Column("c", "", kind="text")]
    n = 300

    class Bare(Table):
        def __init__(self) -> None:
            self.names = [c.name for c in cols]

    spelt = {"a": np.full((n, 2), np.nan), "b": np.full(n, -1), "c": np.zeros(n, dtype=cols[2].dtype)}
    t = Bare()
    left = t.prepared({c.name: c for c in cols}, spelt, n, unwritten_fill=True)
    written = t.prepared({c.name: c for c in cols}, spelt, n)
    assert all(len(p) == n and p.nbytes == 0 for p in left)  # every one a Repeated fill, nothing to write
    np.testing.assert_array_equal(row_checksums(left, 64), row_checksums(written, 64))


@pytest.mark.parametrize(
    ("kind", "values", "expected"),
    [
        ("float", np.full(5, np.nan), True),
        ("float", np.array([np.nan, np.nan, 0.0]), False),
        ("float", np.array([0.0, np.nan]), False),
        ("float", -np.full((3, 2), np.nan), True),  # a NaN of the other sign is still the fill
        ("int", np.array([-1, -1, 7]), False),
        ("int", np.full(4, -1), True),
        ("text", np.array([b"", b"", b"x"], dtype="S4"), False),
        ("text", np.zeros(3, dtype="S4"), True),
        ("float", np.empty(0), False),
    ],
)
def test_all_fill_is_true_only_when_every_value_is_the_fill(kind, values, expected):
    assert all_fill(Column("x", "1" if kind != "text" else "", kind=kind), values) is expected


def test_the_split_an_import_holds_is_the_split_a_later_open_reads(tmp_path):
    src = tmp_path / "t.csv"
    trial_csv(src, 400)
    out = tmp_path / "t.h5"
    with RunFile.create(out, protocol=load_protocol("takuma2014"), imported=True) as run:
        df = pd.read_csv(src)
        run.records.append(
            {
                "trial": df.trial.to_numpy(),
                "P0": df[BASELINE].to_numpy(),
                "P": df[LOADED].to_numpy(),
                "theta": np.radians(df[["theta1_deg", "theta2_deg"]].to_numpy()),
                "F": df[["Fx_N", "Fy_N"]].to_numpy(),
            }
        )
        fit, val = df.trial[df.set == "fit"].to_numpy(), df.trial[df.set == "validation"].tolist()
        run.split.set(fit, val, "imported")
        held = run.split.get()
        assert held["fit"] == fit.tolist() and all(type(i) is int for i in held["fit"])
    with RunFile.open(str(out)) as run:
        assert run.split.get() == held


def test_a_bulk_append_names_the_smallest_repeated_or_stored_id(tmp_path):
    out = tmp_path / "t.h5"
    cols = {"P0": np.full((4, 4), 0.2), "P": np.full((4, 4), 0.25), "theta": np.zeros((4, 2)), "F": np.ones((4, 2))}
    with RunFile.create(out, protocol=load_protocol("takuma2014"), imported=True) as run:
        with pytest.raises(StoreError) as e:
            run.records.append({"trial": np.array([9, 5, 9, 5]), **cols})
        assert str(e.value) == "trial 5 appears twice; ids must be unique."
        run.records.append({"trial": np.array([8, 2, 6, 4]), **cols})
        with pytest.raises(StoreError) as e:
            run.records.append({"trial": np.array([11, 6, 10, 4]), **cols})
        assert str(e.value) == f"trial 4 is already complete in {out}; a stored record is never overwritten."
        assert run.records.ids() == [8, 2, 6, 4]


def test_ids_of_bulk_appends_held_as_arrays_count_as_the_ids_read_back(tmp_path):
    out = tmp_path / "t.h5"
    cols = {"P0": np.full((3, 4), 0.2), "P": np.full((3, 4), 0.25), "theta": np.zeros((3, 2)), "F": np.ones((3, 2))}
    with RunFile.create(out, protocol=load_protocol("takuma2014"), imported=True) as run:
        run.records.append({"trial": np.array([30, 10, 20]), **cols})
        run.records.append({"trial": np.array([5, 7, 6]), **cols})
        assert run.records.id_array().tolist() == [30, 10, 20, 5, 7, 6]
        with pytest.raises(StoreError, match="trial 40 is not a complete trial"):
            run.split.set([30, 40], [5])
        run.split.set([30, 10, 6], [5])
        assert 7 in run.records and 8 not in run.records and len(run.records) == 6
        assert run.records.ids() == [30, 10, 20, 5, 7, 6]
        with pytest.raises(StoreError, match="trial 10 is already complete"):
            run.records.append({"trial": np.array([11, 10, 12]), **cols})
    with RunFile.open(str(out)) as run:
        assert run.records.ids() == [30, 10, 20, 5, 7, 6] and run.records.id_array().tolist() == run.records.ids()
        assert run.split.get()["fit"] == [30, 10, 6]


def test_an_imported_tables_checksums_are_stored_unzipped_and_its_numbers_at_level_1(tmp_path):
    src = tmp_path / "t.csv"
    trial_csv(src, 3000)
    out = tmp_path / "t.h5"
    import_csv(str(src), str(out), protocol="takuma2014")
    with h5py.File(out, "r") as f:
        t = f["entry/trials"]
        assert t["checksum"].compression is None and t["checksum"].fletcher32
        assert t["P"].compression == "gzip" and t["P"].compression_opts == 1 and t["P"].fletcher32
        # 64 bits that look random: deflate would not make them smaller
        ck = t["checksum"]
        assert ck.id.get_storage_size() == ck.id.get_num_chunks() * (8 * ck.chunks[0] + 4)  # each chunk + Fletcher32


def test_an_import_syncs_its_file_once_whole_before_it_is_put_in_place(tmp_path, monkeypatch):
    src = tmp_path / "t.csv"
    trial_csv(src, 300)
    out = tmp_path / "t.h5"
    synced: list[tuple[str, bool]] = []
    real = os.fsync

    def fsync(fd: int) -> None:
        name = os.readlink(f"/proc/self/fd/{fd}")
        if os.path.isfile(name) and Path(name).parent == tmp_path:
            synced.append((Path(name).name, out.exists()))
        real(fd)

    monkeypatch.setattr(os, "fsync", fsync)
    import_csv(str(src), str(out), protocol="takuma2014")
    partial = [(name, there) for name, there in synced if name.endswith(".partial")]
    assert len(partial) == 1 and partial[0][1] is False  # once, before the run file appears
    with RunFile.open(str(out)) as run:
        assert run.verify()["ok"] is True and len(run.records.ids()) == 300
