"""Every kind of run file labcli writes, checked by the field's NeXus validators: nxvalidate's
nxinspect finds no error and no warning, punx no error.  The default plot is one they find.

The validators are installed apart from labcli (see :func:`support.standards.validator`); where
they are not, these tests skip and say how to install them.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from support.standards import make_runs, nxinspect_counts, punx_errors

KINDS = ("force", "push", "rpam-stretch", "rpam-joint", "imported", "upgraded")


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    return make_runs(tmp_path_factory.mktemp("nexus"))


@pytest.mark.parametrize("kind", KINDS)
def test_no_variable_length_text_no_enum_and_units_on_every_number(runs, kind):
    # A variable-length string lives in the global heap, where one flipped bit can hang or crash
    # HDF5 as it reads the attribute; an enum is a type other tools warn about.
    import h5py

    found: list[str] = []

    def check(name: str, obj: object) -> None:
        for key in obj.attrs:  # type: ignore[attr-defined]
            t = obj.attrs.get_id(key).get_type()  # type: ignore[attr-defined]
            if t.get_class() in (h5py.h5t.ENUM, h5py.h5t.VLEN) or (
                isinstance(t, h5py.h5t.TypeStringID) and t.is_variable_str()
            ):
                found.append(f"{name}@{key}")
        if isinstance(obj, h5py.Dataset):
            if h5py.check_vlen_dtype(obj.dtype) is not None or obj.dtype.kind == "O":
                found.append(name)
            if obj.dtype.kind in "iuf" and not obj.attrs.get("units"):
                found.append(f"{name} (no units)")
            if obj.dtype.kind == "S" and "units" in obj.attrs:
                found.append(f"{name} (a text with units)")

    with h5py.File(runs[kind], "r") as f:
        check("/", f)
        f.visititems(check)
        raw = f["entry/raw"]
        virtual = [
            c for c in raw if isinstance(raw[c], h5py.Group) and "value" in raw[c] and raw[c]["value"].is_virtual
        ]
    assert found == []
    # No global heap but the one collection that holds the channels' virtual datasets' mappings
    # (from schema 4; an imported run keeps no channels).
    assert runs[kind].read_bytes().count(b"GCOL") == (1 if virtual else 0)


@pytest.mark.parametrize("kind", KINDS)
def test_nxinspect_finds_nothing(runs, kind):
    warnings, errors, report = nxinspect_counts(runs[kind])
    assert (warnings, errors) == (0, 0), report


@pytest.mark.parametrize("kind", KINDS)
def test_punx_finds_no_error(runs, kind):
    errors, lines = punx_errors(runs[kind])
    assert errors == 0, lines


def test_the_validators_would_see_what_they_object_to(runs, tmp_path):
    # Schema 2's ways, put back into a run: a field named plan_set (a NeXus set point, so a
    # number) and an @axes with a '.' placeholder; each validator says so.
    import shutil

    import h5py
    import numpy as np

    bad = tmp_path / "bad.h5"
    shutil.copy(runs["force"], bad)
    with h5py.File(bad, "a") as f:
        t = f["entry/trials"]
        t.move("plan_set_", "plan_set")
        t.attrs["NX_class"], t.attrs["signal"], t.attrs["axes"] = "NXdata", "P", np.array([b"trial", b"."])
    warnings, _, report = nxinspect_counts(bad)
    assert warnings > 0 and "plan_set" in report
    errors, lines = punx_errors(bad)
    assert errors > 0 and "@axes" in lines


def test_ci_installs_the_validators_pinned_here_and_requires_them():
    # .ci/run makes the validators' environment with .ci/validators and says they are required
    # before it runs the README's test command, so a validator missing in CI fails, never skips.
    from support.standards import ROOT, VALIDATORS

    script = (ROOT / ".ci" / "validators").read_text()
    for pin in VALIDATORS.values():
        assert f"'{pin}'" in script
    assert "nxvalidate==0.3.5b3" in VALIDATORS.values()  # a pre-release: only an exact pin installs it
    run = (ROOT / ".ci" / "run").read_text().splitlines()
    at = {
        key: next(i for i, line in enumerate(run) if key in line and not line.lstrip().startswith("#"))
        for key in (
            ".ci/validators",
            'LABCLI_NEXUS_VALIDATORS="$validators"',
            "LABCLI_STANDARDS=required",
            'bash -c "$cmd"',
        )
    }
    assert at[".ci/validators"] < at["LABCLI_STANDARDS=required"] < at['bash -c "$cmd"']
    assert "export" in run[at["LABCLI_STANDARDS=required"]]


@pytest.mark.parametrize("required", [False, True])
def test_a_missing_validator_skips_or_fails_where_required(monkeypatch, tmp_path, required):
    from support.standards import need, validator

    monkeypatch.setenv("LABCLI_NEXUS_VALIDATORS", str(tmp_path))  # a folder without them
    monkeypatch.setenv("LABCLI_STANDARDS", "required" if required else "")
    outcome = pytest.fail.Exception if required else pytest.skip.Exception
    with pytest.raises(outcome, match=f"punx is not installed in {tmp_path}"):
        validator("punx")
    with pytest.raises(outcome, match="no_such_validator is not installed"):
        need("no_such_validator_module", "no_such_validator")
