"""classify's whole-array shortcuts say what the object-by-object and push-by-push code said, to the last bit.

The objects' statistics and the bands' verdicts (:func:`object_stats_many`,
:meth:`CategoryModel.predict_groups`) against :func:`object_stats` and ``predict`` one object at a
time, as the report was built before; the streamed JSON's lines (:func:`push_lines`, and
:func:`push_text` that joins them) against ``json.dumps`` of each push's item; the objects' items
(:func:`object_items`) against a row at a time.
"""

from __future__ import annotations

import json
import math
from collections import Counter
from collections.abc import Mapping
from typing import Any

import numpy as np
import pandas as pd
import pytest

from labcli.core.protocol import load_protocol
from labcli.errors import ModelError
from labcli.papers.takuma2014.models.categories import CategoryModel
from labcli.papers.takuma2014.models.classify import (
    ClassifyReport,
    _num,
    classify_pushes,
    object_items,
    push_items,
    push_lines,
    push_text,
    write_report_json,
)
from labcli.papers.takuma2014.models.stiffness import object_stats, object_stats_many
from labcli.papers.takuma2014.models.takuma import TakumaModel
from labcli.papers.takuma2014.protocol import load_plan
from labcli.papers.takuma2014.sim.drive import simulate_pushes, simulate_weight_trials
from labcli.papers.takuma2014.sim.nonideal import NonIdeal
from labcli.papers.takuma2014.sim.objects import DEMO_OBJECTS
from labcli.papers.takuma2014.sim.rig import SimRig


@pytest.fixture(scope="module")
def lab() -> dict[str, Any]:
    """A paper-form model and an archive of pushes: 6 objects x 6 pushes tiled 25 times, varied."""
    force, push = load_protocol("takuma2014"), load_protocol("takuma2014-stiffness")
    rig = SimRig(seed=1, nonideal=NonIdeal.ideal())
    trials = simulate_weight_trials(rig, load_plan(force).iloc[::2], calibration=force.calibration)
    model = TakumaModel(geometry=force.settings.rig, protocol=force.name).fit(trials)
    # Without its fit statistics the model has no error budget (models/budget.py), so the bands'
    # confidences are the pushes' shares, which the one-object-at-a-time code below rebuilds.
    model.fit_stats = {}
    pool = simulate_pushes(rig, DEMO_OBJECTS, calibration=push.calibration, pushes_per_object=6, labelled=True)
    rng = np.random.default_rng(5)
    n = 25 * len(pool)
    table = pool.iloc[np.arange(n) % len(pool)].reset_index(drop=True)
    table["push"] = np.arange(1, n + 1)
    copy = np.arange(n) // len(pool)
    table["object"] = [f"{o}#{c}" if c % 7 else f"{o}-ü{c}" for o, c in zip(table["object"], copy, strict=True)]
    table.loc[rng.random(n) < 0.3, "phi_deg"] = np.nan  # the push direction solved
    table.loc[rng.random(n) < 0.05, "d_m"] = 0.0  # no deformation: flagged
    table.loc[table["object"].str.endswith("#3"), "d_m"] = 0.0  # objects with no usable push
    table["category"] = np.where(copy < 3, table["category"], "")  # three copies are the references
    return {"model": model, "table": table, "bands": push.settings.push.stiffness_bands_N_per_m}


def object_by_object(res: Any, table: pd.DataFrame, cat_model: CategoryModel) -> pd.DataFrame:
    """The objects' rows as classify built them one object at a time (statistics, bands, reference scores)."""
    pushes, rows = res.pushes, []
    k, flag = pushes["k_N_per_m"].to_numpy(), pushes["flag"].to_numpy(dtype=bool)
    use = ~flag & np.isfinite(k)
    labels = np.array([c if isinstance(c, str) else "" for c in table["category"]], dtype=object)
    for name in pd.unique(table["object"]):
        sel = np.flatnonzero(table["object"].to_numpy() == name)
        known = sorted({c for c in labels[sel] if c})
        row: dict[str, Any] = {"object": name, "known_category": known[0] if known else ""}
        row.update(object_stats(k[sel], flag[sel] | ~np.isfinite(k[sel])))
        row["true_k_N_per_m"] = float(np.nanmean(table["true_stiffness_N_per_m"].to_numpy()[sel]))
        samples = k[sel[use[sel]]]
        if samples.size == 0:
            top = Counter(r for r in pushes["reason"].to_numpy()[sel] if r).most_common(1)[0][0]
            row.update(
                category="",
                confidence=0.0,
                z=math.nan,
                method=cat_model.method,
                note=f"no usable push ({top})",
                evidence="uncertain",
                z_by_category={},
            )
            rows.append(row)
            continue
        scorer, note = cat_model, ""
        if cat_model.method == "reference" and row["known_category"]:
            others = use & (labels != "")
            others[sel] = False
            scorer = CategoryModel("reference", min_std_log_k=cat_model.min_std_log_k).fit(
                k[others], list(labels[others])
            )
        p = scorer.predict([samples], names=[name])
        row.update(
            category=p.category[0],
            confidence=float(p.confidence[0]),
            z=float(p.z[0]),
            method=p.method,
            note="; ".join(t for t in (note, p.note[0]) if t),
            evidence=p.evidence[0],
            z_by_category=p.distances[0],
        )
        rows.append(row)
    return pd.DataFrame(rows)


@pytest.mark.parametrize("method", ["bands", "reference"])
def test_every_object_row_is_the_one_object_at_a_time_gave(lab: dict[str, Any], method: str) -> None:
    res = classify_pushes(lab["table"], lab["model"], bands=lab["bands"], method=method, allow_unusable=True)
    assert (res.objects["n_used"] == 0).sum() == 6 and res.objects["category"].nunique() > 1
    want = object_by_object(res, lab["table"], res.model)
    pd.testing.assert_frame_equal(res.objects, want, check_exact=True)
    with pytest.raises(ModelError, match=r"Object 'pet-1#3' has no usable push: all 6 are flagged"):
        classify_pushes(lab["table"], lab["model"], bands=lab["bands"], method=method)


@pytest.mark.parametrize("seed", range(5))
def test_statistics_and_band_verdicts_of_many_groups_are_each_group_s_own(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n, groups = 5000, 700
    group = np.sort(rng.integers(0, groups, n)) if seed % 2 else rng.integers(0, groups, n)
    k = rng.lognormal(7.0, 1.3, n)
    odd = rng.random(n) < 0.05
    k[odd] = rng.choice([np.nan, np.inf, 0.0, -5.0], size=int(odd.sum()))
    flag = rng.random(n) < 0.2
    many = object_stats_many(k, flag, group, groups)
    bands = CategoryModel.from_bands({"soft": [0, 1000], "medium": [1000, 4000], "hard": [4000, None]})
    for g in range(groups):
        one = object_stats(k[group == g], flag[group == g] | ~np.isfinite(k[group == g]))
        assert one == pytest.approx({key: v[g] for key, v in many.items()}, nan_ok=True, rel=0, abs=0)
    usable = [g for g in range(groups) if many["n_used"][g] > 0]
    keep = ~flag & np.isin(group, usable)
    number = np.searchsorted(usable, group[keep])
    p = bands.predict_groups(k[keep], number, len(usable))
    q = bands.predict([k[keep][number == i] for i in range(len(usable))])
    assert (p.category, p.note, p.evidence, p.distances) == (q.category, q.note, q.evidence, q.distances)
    assert np.array_equal(p.confidence, q.confidence)


def test_the_streamed_pushes_are_json_dumps_of_each_push_item(lab: dict[str, Any]) -> None:
    res = classify_pushes(lab["table"], lab["model"], bands=lab["bands"], method="bands", allow_unusable=True)
    res.pushes.loc[3, "source"] = "run"  # a source column, as a reference run adds
    # A float's text is made once per distinct value of a repeating column and taken from the
    # estimate where the force used is the same float: equal is not enough (-0.0 == 0.0).
    df = res.pushes
    df.loc[7, ["Fx_N", "Fx_used_N", "R_m", "phi_deg"]] = [0.0, -0.0, -0.0, -0.0]
    df.loc[8, ["Fx_N", "Fx_used_N", "R_m", "phi_deg"]] = [-0.0, 0.0, 0.0, 0.0]
    df.loc[9, ["Fy_N", "Fy_used_N"]] = [np.nan, 1.5]
    df.loc[10, ["Fy_N", "Fy_used_N"]] = [2.5, np.nan]
    df.loc[11, ["Fy_N", "Fy_used_N", "R_m"]] = [np.inf, np.inf, 0.1 + 0.2]
    df.loc[90:110, "Fx_used_N"] += 0.25  # a component rebuilt along the push, across a chunk's end
    report = ClassifyReport(res, "p.csv", "m.json", None, load_protocol("takuma2014-stiffness"), "pressure-only")
    lines = [line for chunk in push_lines(report, chunk=97) for line in chunk]
    assert lines == [json.dumps(item, allow_nan=False) for item in push_items(report)]
    for chunk in (97, 1):  # what write_report_json streams: each chunk's lines joined
        assert list(push_text(report, chunk=chunk)) == [",\n    ".join(c) for c in push_lines(report, chunk=chunk)]
    assert '"Fx_N": 0.0, "Fy_N"' in lines[7] and '"Fx_used_N": -0.0' in lines[7] and '"R_mm": -0.0' in lines[7]
    assert '"Fx_N": -0.0' in lines[8] and '"Fx_used_N": 0.0' in lines[8] and '"phi_deg": 0.0' in lines[8]
    assert '"Fy_N": null' in lines[9] and '"Fy_used_N": 1.5' in lines[9] and '"Fy_used_N": null' in lines[10]
    assert '"Fy_used_N": null' in lines[11] and '"R_mm": 300.00000000000006' in lines[11]
    assert f'"Fx_used_N": {float(df.loc[100, "Fx_N"]) + 0.25!r}' in lines[100]
    assert any('"phi_deg": null' in line for line in lines) and any('"flagged": true' in line for line in lines)
    assert any("\\u00fc" in line for line in lines)  # the object names' u-umlaut, as json.dumps escapes it
    res.pushes.loc[5, "R_m"] = 1e306  # scaled to mm it overflows: refused as json.dumps refuses it
    with pytest.raises(ValueError, match="Out of range float values are not JSON compliant"):
        write_report_json(report, open("/dev/null", "w"))


def _object_item(row: Mapping[str, Any], method: str) -> dict[str, Any]:
    """One object's summary from its row, as the report made it before it went column by column."""
    item = {
        "object": str(row["object"]),
        # Under bands a known category is only compared with the bands' answer, not used to place them.
        "role": ("reference" if method == "reference" else "given") if row.get("known_category") else "unknown",
        "category_given": str(row.get("known_category") or ""),
        "n": int(row["n_pushes"]),
        "n_used": int(row["n_used"]),
        "n_flagged": int(row["n_flagged"]),
        "k_mean_N_per_m": _num(row["k_mean_N_per_m"]),
        "k_sd_N_per_m": _num(row["k_std_N_per_m"]),
        "k_median_N_per_m": _num(row["k_median_N_per_m"]),
        "log_k_mean": _num(row["log_k_mean"]),
        "log_k_sd": _num(row["log_k_std"]),
        "category": str(row.get("category") or ""),
        "confidence": _num(row.get("confidence")),
        "z": _num(row.get("z")),
        "method": str(row.get("method") or method),
        "note": str(row.get("note") or ""),
        "evidence": str(row.get("evidence") or ""),
        "z_by_category": {str(c): _num(v) for c, v in dict(row.get("z_by_category") or {}).items()},
    }
    if "true_k_N_per_m" in row:
        item["true_k_N_per_m"] = _num(row["true_k_N_per_m"])
    if "log_k_se" in row:
        item["log_k_se"] = _num(row["log_k_se"])  # the standard error behind a band's confidence
    return item


def test_the_objects_items_are_what_each_row_gave(lab: dict[str, Any]) -> None:
    res = classify_pushes(lab["table"], lab["model"], bands=lab["bands"], method="bands", allow_unusable=True)
    report = ClassifyReport(res, "p.csv", "m.json", None, load_protocol("takuma2014-stiffness"), "pressure-only")
    items = object_items(report)
    assert items == [_object_item(row, res.method) for row in res.objects.to_dict("records")]
    assert json.dumps(items) == json.dumps([_object_item(row, res.method) for row in res.objects.to_dict("records")])
    assert any(i["k_mean_N_per_m"] is None for i in items) and any(i["role"] == "given" for i in items)
    assert any(i["role"] == "unknown" for i in items) and any(i["z_by_category"] for i in items)
