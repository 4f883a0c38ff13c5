"""A fitted model as C (``labcli export-model``) computes what the host's predict computes.

The header is built into the firmware's model code on the host (``make -C firmware
MODEL=... host-tools``: the same C the chip runs, in the host's 32-bit floats, behind the pipe
of firmware/test/model_tool.c) and held against ``PostureModel.predict`` / ``TakumaModel.predict``
(pressure-only, as ``labcli validate`` applies a model) on random pressures and rest postures and
on the edge cases: bad pressures, the paper's clipped angles, a straight arm.  Three models: the
posture form without the friction terms (the sample force run refitted, ``--no-friction-terms``),
the bent protocol's (the paper's angles with the posture form's forces, likewise) and the paper's
form alone (the sample model file); and the posture form with the sleeves' friction terms
(``--friction-terms``, ``labcli fit``'s default), given each row's motion into
its baseline, and the erf its fade takes on the chip.  The chip itself, on simavr, is in
tests/core/test_firmware_model.py.
"""

from __future__ import annotations

import copy
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from support.firmware_build import FIRMWARE, make, need_avr_tools, need_host_compiler

from labcli.cli import cli
from labcli.core.boardlines import ESTIMATE_FLAGS
from labcli.papers.takuma2014.models.posture import PostureModel, load_force_model
from labcli.papers.takuma2014.models.takuma import force_design

ROOT = Path(__file__).resolve().parents[3]
QUANTITIES = ("theta1", "theta2", "Fx", "Fy")
BITS = {name: bit for bit, name in ESTIMATE_FLAGS.items()}


@pytest.fixture(scope="module")
def models(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Model files of each form: fitted here from the sample runs, and the sample paper-form model."""
    d = tmp_path_factory.mktemp("models")
    out = {"paper": ROOT / "sample_runs" / "force-paper.model.json"}
    for name, run_name, extra in (
        ("force", "force", ["--no-friction-terms"]),
        ("bent", "bent", ["--no-friction-terms"]),
        ("friction", "force", ["--friction-terms"]),
    ):
        run = d / f"{run_name}.h5"
        shutil.copy(ROOT / "sample_runs" / f"{run_name}.h5", run)
        result = CliRunner().invoke(cli, ["fit", str(run), *extra, "-o", str(d / f"{name}.json")])
        assert result.exit_code == 0, result.output
        out[name] = d / f"{name}.json"
    return out


def model_tool(model: Path, build: Path) -> Path:
    need_host_compiler()
    header = build / "model.h"
    result = CliRunner().invoke(cli, ["export-model", str(model), "--c", str(header)])
    assert result.exit_code == 0, result.output
    make(build, str(build / "host" / "model_tool"), defs="", model=header)
    return build / "host" / "model_tool"


def chip(tool: Path, P0: np.ndarray, P: np.ndarray, th0: np.ndarray, moved: np.ndarray | None = None) -> np.ndarray:
    """(n, 9): theta1, theta2, Fx, Fy, their standard errors, flags (``moved``: each row's motion into its baseline)."""
    extra = np.empty((len(P0), 0)) if moved is None else moved
    lines = "".join(
        "P " + " ".join(f"{v:.9g}" for v in np.r_[P0[i], P[i], th0[i], extra[i]]) + "\n" for i in range(len(P0))
    )
    out = subprocess.run([str(tool)], input=lines, capture_output=True, text=True, timeout=60, check=True).stdout
    return np.array([[float(x) for x in row.split()] for row in out.splitlines()])


def inputs(seed: int, n: int = 1500) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    P0 = rng.uniform(0.12, 0.45, (n, 4))
    P = P0 * (1.0 + rng.normal(0.0, 0.03, (n, 4)))
    th0 = rng.normal(0.0, 0.3, (n, 2))
    # Edge cases: bad pressures, a pressure at the chambers' floor, a straight arm, huge drops.
    P0[0, 1], P[1, 2], P[2, 0], P0[3] = 0.0, -0.1, np.nan, P[3]
    th0[4] = 0.0
    P[5] = P0[5] * [0.5, 1.6, 0.4, 1.9]
    return P0, P, th0


def host(
    model_path: Path, P0: np.ndarray, P: np.ndarray, th0: np.ndarray, moved: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Values (n, 4), standard errors (n, 4; zeros for the paper's form), the flag bits and the
    standard errors the flags judge (before the fit plan's direction term), from the host."""
    m = load_force_model(model_path)
    if isinstance(m, PostureModel):
        out = m.predict(P0, P, th0, motion_in=moved)
        se = np.column_stack([out["se"][q] for q in QUANTITIES])
        # The flags judge the standard errors before the fit plan's direction term (routes.held_out_variances).
        plain = copy.copy(m)
        plain.held_out_variance = {}
        own = plain.predict(P0, P, th0, motion_in=moved)["se"]
        judged = np.column_stack([own[q] for q in QUANTITIES])
        limits = np.array([m.limits[q] for q in QUANTITIES])
    else:
        out = m.predict(P0, P)
        se, limits = np.zeros((len(P0), 4)), np.full(4, np.inf)
        judged = se
    values = np.column_stack([out[k] for k in ("theta1_rad", "theta2_rad", "Fx_N", "Fy_N")])
    bits = np.zeros(len(P0), np.int64)
    bad = np.array(["bad-pressure" in f for f in out["flags"]])
    for q, name in enumerate(QUANTITIES):
        bits |= np.where(~bad & ~(judged[:, q] <= limits[q]), BITS[f"{name}-uncertain"], 0)
    for i, flags in enumerate(out["flags"]):
        for name in ("bad-pressure", "theta1-clipped", "theta2-clipped", "singular-jacobian"):
            if name in flags:
                bits[i] |= BITS[name]
    return values, se, bits, judged


def motions(seed: int, n: int) -> np.ndarray:
    """The joints' motions into the baselines (rad): back from a load's 0.5-3 deg, or within the fade."""
    rng = np.random.default_rng(seed)
    m = rng.normal(0.0, np.radians(1.5), (n, 2))
    m[::4] = rng.normal(0.0, np.radians(0.1), (len(m[::4]), 2))
    return m


@pytest.mark.parametrize("form", ["force", "bent", "paper", "friction"])
def test_the_chips_model_computes_the_hosts_predictions(form, models, tmp_path):
    tool = model_tool(models[form], tmp_path)
    P0, P, th0 = inputs(seed={"force": 1, "bent": 2, "paper": 3, "friction": 4}[form])
    moved = motions(5, len(P0)) if form == "friction" else None
    got = chip(tool, P0, P, th0, moved)
    values, se, bits, judged = host(models[form], P0, P, th0, moved)
    ok = np.all(np.isfinite(values), axis=1)
    # The target: 1 % of each quantity's range, on every estimate the host does not flag singular
    # (on those, a few 1e-5 of it).  Near a straight arm the paper's (J^-1)^T grows as
    # 1/sin(theta2), and the float's rounding with it: where the host flags the estimate singular
    # the two differ by up to 6 % of Fx's range with the sample runs' paper model (0.8 % with an
    # earlier one), and what the chip must give there is the same flag (checked below).
    kept = ok & ((bits & BITS["singular-jacobian"]) == 0)
    span = values[kept].max(axis=0) - values[kept].min(axis=0)
    err = np.abs(got[kept, :4] - values[kept])
    assert np.all(err.max(axis=0) <= 1e-2 * span), (err.max(axis=0) / span, form)
    clean = ok & ((bits & (BITS["singular-jacobian"] | BITS["bad-pressure"])) == 0)
    assert np.all(np.abs(got[clean, :4] - values[clean]).max(axis=0) <= 1e-3 * span)
    assert np.all(np.isfinite(got[:, :4]))  # never a nan or inf on the wire, as the host's predict
    # Flags: the same bits, but where a standard error sits within float rounding of its limit.
    m = load_force_model(models[form])
    limits = np.array([getattr(m, "limits", {}).get(q, np.inf) for q in QUANTITIES])
    differ = got[:, 8].astype(np.int64) != bits
    borderline = np.any(np.abs(judged - limits) <= 1e-4 * limits, axis=1)
    assert not np.any(differ & ~borderline), np.flatnonzero(differ & ~borderline)[:5]
    if isinstance(m, PostureModel):
        rel = np.abs(got[ok, 4:8] - se[ok]) / np.maximum(se[ok], 1e-12)
        assert np.nanmax(np.where(np.isfinite(se[ok]), rel, 0.0)) < 1e-2  # the chip's closed-form dF/dtheta
    assert bits[0] == bits[1] == bits[2] == BITS["bad-pressure"] == got[0, 8] == got[1, 8] == got[2, 8]


def near_straight(model: Path, seed: int, n: int = 300) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pressures whose Eq. 35 gives sin(theta2) of 1e-6 to 1e-2 either way (the straight arm's
    singular Jacobian), and each row's exact sin(theta2) in doubles."""
    b = load_force_model(model).coefficients
    beta = np.array([b[k] for k in ("beta_theta2_L1", "beta_theta2_R1", "beta_theta2_L2", "beta_theta2_R2")])
    rng = np.random.default_rng(seed)
    P0 = rng.uniform(0.25, 0.35, (n, 4))
    u = rng.normal(0.0, 2e-3, (n, 4))
    s = rng.choice([-1.0, 1.0], n) * 10.0 ** rng.uniform(-6.0, -2.0, n)
    u[:, 3] = (s - u[:, :3] @ beta[:3]) / beta[3]
    # In floats both, so that the chip and the host read the same pressures.
    P0, P = P0.astype(np.float32).astype(float), (P0 / (1.0 + u)).astype(np.float32).astype(float)
    return P0, P, (P0 / P - 1.0) @ beta


def test_the_paper_forms_straight_arm_differs_by_the_floats_rounding_of_sin_theta2_alone(models, tmp_path):
    """Near a straight arm Eqs. 36-37's (J^-1)^T grows as 1/sin(theta2): the chip's forces there
    differ from the host's by as much as its 32-bit sin(theta2) does (docs/hardware.md).  Given the
    chip's own angles the host computes the chip's forces: no term or coefficient is lost."""
    tool = model_tool(models["paper"], tmp_path)
    P0, P, s = near_straight(models["paper"], seed=6)
    got = chip(tool, P0, P, np.zeros((len(P0), 2)))
    m = load_force_model(models["paper"])
    b = m.coefficients
    beta = np.array([b[k] for k in ("beta_theta2_L1", "beta_theta2_R1", "beta_theta2_L2", "beta_theta2_R2")])
    u = P0 / P - 1.0
    # The float argument: P0 / P rounded to 2^-24 of itself and the 1 taken off exactly, so each
    # ratio u carries 2^-24 (1 + u), 6e-8, however small it is; Eq. 35's sum of four beta u adds
    # 2^-24 of its terms per operation, and the chip's asin and the host's sin 2^-24 of sin(theta2)
    # each.  Near a straight arm the first is all of it, against a sin(theta2) of 1e-6.
    eps = 2.0**-24
    bound = eps * (np.abs(u + 1.0) @ np.abs(beta) + 6.0 * np.abs(u) @ np.abs(beta) + 4.0 * np.abs(s))
    s_chip = np.sin(got[:, 1])
    assert np.all(np.abs(s_chip - s) <= bound), np.max(np.abs(s_chip - s) / bound)
    # The forces at the chip's angles: the chip's, to a float's rounding of their terms.
    at = m.predict(P0, P, mode="measured-angles", theta=got[:, :2])
    exact = m.predict(P0, P)
    # Their terms (Eqs. 36-37's designs times beta) cancel to a thousandth of their size: the
    # rounding is of the terms', a float's 6e-8 a few times over each.
    h2, h3 = m.geometry["h2"], m.geometry["h3"]
    designs = force_design(P0, P, got[:, :2], h2, h3)
    for k, name, X in ((2, "Fx_N", designs[0]), (3, "Fy_N", designs[1])):
        terms = np.abs(X) @ np.abs(np.array([b[f"beta_{name[:2]}{j}"] for j in range(1, 7)]))
        assert np.all(np.abs(got[:, k] - at[name]) <= 1e-5 * terms), (
            name,
            np.max(np.abs(got[:, k] - at[name]) / terms),
        )
    # Against the host's own angles the relative difference is the sine's: up to bound / |s|,
    # over 1 % of Fy on the rows nearest straight (what the benchmark's singular rows show).
    rel = np.abs(got[:, 3] - exact["Fy_N"]) / np.abs(exact["Fy_N"])
    assert np.all(rel <= 2.0 * bound / np.abs(s) + 1e-4)
    assert rel.max() > 1e-2
    assert all("singular-jacobian" in f for f in exact["flags"])


def test_the_header_names_its_model_and_calibration(models, tmp_path):
    header = tmp_path / "model.h"
    result = CliRunner().invoke(cli, ["export-model", str(models["bent"]), "--c", str(header)])
    assert result.exit_code == 0, result.output
    text = header.read_text()
    m = load_force_model(models["bent"])
    assert isinstance(m, PostureModel)
    import hashlib

    digest = hashlib.sha256(models["bent"].read_bytes()).hexdigest()
    assert f'#define MODEL_ID "{digest[:8]}"' in text and digest in text
    assert result.output.splitlines()[0] == (
        f"Wrote {header}: the posture model {models['bent']} (id {digest[:8]}; "
        f"{', '.join(f'{q} {m.route(q)}' for q in QUANTITIES)}), calibration of protocol {m.protocol}."
    )
    assert f"#define MODEL_NT {len(m.torque_terms)} /* torque terms: {', '.join(m.torque_terms)} */" in text
    # The reference calibration: 5/16380 MPa per count from 819 counts, 340 deg over 4095 counts.
    assert "MODEL_GAIN[6] = {0.000305250305f, 0.000305250305f, 0.000305250305f, 0.000305250305f, 0.00144911342f" in text
    assert "MODEL_ZERO[6] = {819.0f, 819.0f, 819.0f, 819.0f, 2048.0f, 2048.0f};" in text


@pytest.mark.parametrize(
    "make_file, message",
    [
        (lambda p: None, "Error: The model file {p} does not exist; write one with `labcli fit`."),
        (
            lambda p: p.write_text("[1, 2"),
            "Error: {p} is not a model file (not JSON text); pass the .json file `labcli fit` wrote.",
        ),
        (
            lambda p: p.write_text('{"kind": "rpam-stretch-fit"}'),
            "Error: {p} names no model schema (it holds an object without a 'schema' key), so no paper reads it; "
            "pass the model .json file `labcli fit` wrote for a force run.",
        ),
        (
            lambda p: p.write_text('{"schema": "someone-elses-model"}'),
            "Error: No installed paper writes models of schema 'someone-elses-model'; pass a .json file "
            "`labcli fit` wrote.",
        ),
        (
            lambda p: p.write_text('{"schema": "labcli-takuma-model", "version": 1, "form": "paper"}'),
            "Error: The model file {p} lacks the key 'protocol'; refit with `labcli fit`.",
        ),
    ],
)
def test_bad_model_files_are_refused_in_one_sentence(make_file, message, tmp_path):
    p = tmp_path / "m.json"
    make_file(p)
    result = CliRunner().invoke(cli, ["export-model", str(p), "--c", str(tmp_path / "model.h")])
    assert result.exit_code == 1
    assert result.output == message.format(p=p) + "\n"
    assert not (tmp_path / "model.h").exists()


def test_the_firmware_makefile_refuses_a_missing_model(tmp_path):
    need_host_compiler()
    proc = subprocess.run(
        ["make", "-C", str(FIRMWARE), f"BUILD={tmp_path}", f"MODEL={tmp_path / 'none.h'}", "host-tools"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode != 0
    assert f"MODEL={tmp_path / 'none.h'}: no such file (write one with labcli export-model M.json --c model.h)" in (
        proc.stderr
    )


def test_the_friction_terms_read_the_motion_into_the_baseline_on_the_chip(models, tmp_path):
    """The friction model's header carries the terms and their fade; without a motion (the first
    load) the chip computes the host's prediction without one, and the motion changes Fx by the
    friction's share, as on the host."""
    tool = model_tool(models["friction"], tmp_path)
    m = load_force_model(models["friction"])
    assert isinstance(m, PostureModel) and m.uses_history
    text = (tmp_path / "model.h").read_text()
    assert "#define MODEL_HAS_FRICTION 1" in text and "MODEL_FRICTION_WIDTH[2]" in text
    P0, P, th0 = inputs(seed=6, n=300)
    P0, P, th0 = P0[6:], P[6:], th0[6:]  # the ordinary rows
    none = chip(tool, P0, P, th0)
    values, _, _, _ = host(models["friction"], P0, P, th0)
    span = np.ptp(values, axis=0)
    assert np.all(np.abs(none[:, :4] - values).max(axis=0) <= 1e-3 * span)
    moved = motions(7, len(P0))
    given = chip(tool, P0, P, th0, moved)
    shift = given[:, 2] - none[:, 2]
    want = host(models["friction"], P0, P, th0, moved)[0][:, 2] - values[:, 2]
    assert np.max(np.abs(want)) > 0.1  # N: the history moves Fx
    assert np.max(np.abs(shift - want)) <= 1e-3 * span[2]


def test_the_chips_erf_is_within_its_bound(tmp_path, models):
    """model_erf (Abramowitz & Stegun 7.1.26, for a libc without erf): within 5e-7 of erf (the
    formula's 1.5e-7 and the float's rounding of 1 - ...; measured 4.1e-7), a thousandth of the
    fade's width in the motion, and its slope within 1e-6 of 2 exp(-x^2) / sqrt(pi), from the fade's
    middle to far past it."""
    from scipy.special import erf

    tool = model_tool(models["friction"], tmp_path)
    x = np.r_[np.linspace(-6.0, 6.0, 2401), 1e-6, -1e-6, 0.0]
    out = subprocess.run(
        [str(tool)], input="".join(f"E {v:.9g}\n" for v in x), capture_output=True, text=True, timeout=60, check=True
    ).stdout
    got = np.array([[float(v) for v in row.split()] for row in out.splitlines()])
    xf = x.astype(np.float32).astype(float)
    assert np.max(np.abs(got[:, 0] - erf(xf))) <= 5e-7
    assert np.max(np.abs(got[:, 1] - 2.0 / np.sqrt(np.pi) * np.exp(-(xf**2)))) <= 1e-6
    assert np.all(np.diff(got[:2401, 0]) >= 0.0)  # monotone: a sign never flips on rounding


def flash_tables(text: str) -> dict[str, bytes]:
    """Each ``__flash`` table of a header: its bytes on the chip (float, uint8_t, int8_t)."""
    import re

    ctypes = {"float": np.float32, "uint8_t": np.uint8, "int8_t": np.int8}
    out = {}
    for ctype, name, body in re.findall(r"static const __flash (\w+) (\w+)\S* = (\{.*\});", text):
        numbers = re.findall(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?", body)
        out[name] = np.array([float(x) for x in numbers]).astype(ctypes[ctype]).tobytes()
    return out


def elf_tables(elf: Path) -> dict[str, tuple[int, bytes]]:
    """Each MODEL_ table the linked firmware keeps in flash: its address and bytes (avr-nm, avr-objcopy)."""
    image = elf.with_suffix(".text.bin")
    subprocess.run(["avr-objcopy", "-O", "binary", "-j", ".text", str(elf), str(image)], check=True)
    flash = image.read_bytes()
    nm = subprocess.run(["avr-nm", "-S", str(elf)], capture_output=True, text=True, check=True).stdout
    out = {}
    for line in nm.splitlines():
        parts = line.split()
        if len(parts) == 4 and parts[3].startswith("MODEL_") and parts[2] in "tT":
            at, size = int(parts[0], 16), int(parts[1], 16)
            out[parts[3]] = (at, flash[at : at + size])
    return out


@pytest.mark.parametrize("form", ["force", "bent", "paper", "friction"])
def test_every_sample_run_model_builds_for_the_chip_with_its_own_tables(form, models, tmp_path):
    """The sample runs are the literature rig's: each of their models builds into the firmware
    (avr-gcc -Werror, and make() refuses any warning besides), and every table the chip reads holds
    the header's bytes, at an address of its own.  avr-gcc 5 folds two read-only tables of the same
    bytes into one and then warns that the other is uninitialised in program memory (the force run's
    model without the friction terms has its torque terms dP_L1..dP_R2, {0, 1, 2, 3}, equal to the
    pressures' channels); the firmware's -fno-ipa-icf-variables keeps each, so the header holds the
    model's numbers alone, no table longer than the model's terms."""
    need_avr_tools()
    header = tmp_path / "model.h"
    assert CliRunner().invoke(cli, ["export-model", str(models[form]), "--c", str(header)]).exit_code == 0
    out = make(tmp_path / "build", "firmware", defs="-Werror", model=header)
    assert "-Werror" in out and "-fno-ipa-icf-variables" in out
    assert (tmp_path / "build" / "labcli_rig.hex").read_text().endswith(":00000001FF\n")
    tables = flash_tables(header.read_text())
    assert tables["MODEL_P_CHANNEL"] == bytes([0, 1, 2, 3]) and tables["MODEL_POT_CHANNEL"] == bytes([4, 5])
    m = load_force_model(models[form])
    if isinstance(m, PostureModel):
        from labcli.papers.takuma2014.models.posture import FRICTION_TERMS, TORQUE_TERMS

        known = TORQUE_TERMS + FRICTION_TERMS
        assert tables["MODEL_TORQUE_TERM"] == bytes(known.index(t) for t in m.torque_terms)
    kept = elf_tables(tmp_path / "build" / "labcli_rig.elf")
    assert {"MODEL_P_CHANNEL", "MODEL_POT_CHANNEL", "MODEL_GAIN", "MODEL_ZERO"} <= set(kept)
    assert {name: data for name, (_, data) in kept.items()} == {name: tables[name] for name in kept}
    assert len({at for at, _ in kept.values()}) == len(kept)  # none folded into another


def test_a_header_of_before_the_direction_term_still_builds_and_gives_the_plain_errors(models, tmp_path):
    """A header exported before the fit plan's direction term (no MODEL_HAS_HELD_OUT, no
    MODEL_HELD_OUT_VAR) builds as it did, and its chip gives the standard errors without the term."""
    need_host_compiler()
    header = tmp_path / "model.h"
    assert CliRunner().invoke(cli, ["export-model", str(models["force"]), "--c", str(header)]).exit_code == 0
    text = header.read_text()
    assert "#define MODEL_HAS_HELD_OUT 1\n" in text
    assert load_force_model(models["force"]).held_out_variance, "the sample model carries the term"
    old = "".join(
        line
        for line in text.splitlines(keepends=True)
        if "MODEL_HAS_HELD_OUT" not in line and "HELD_OUT_VAR" not in line
    )
    header.write_text(old)
    make(tmp_path, str(tmp_path / "host" / "model_tool"), defs="", model=header)
    P0, P, th0 = inputs(seed=6, n=200)
    got = chip(tmp_path / "host" / "model_tool", P0, P, th0)
    _, se, _, judged = host(models["force"], P0, P, th0)
    ok = np.all(np.isfinite(judged), axis=1) & np.all(judged > 0, axis=1)
    assert np.allclose(got[ok, 4:8], judged[ok], rtol=1e-2)  # the plain errors
    assert np.any(se[ok] > judged[ok] * 1.02)  # which the term would have widened
