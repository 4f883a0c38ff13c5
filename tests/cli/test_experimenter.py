"""A scripted experimenter at a terminal (pexpect): what the session does when the person at the rig errs.

``labcli acquire`` runs on a pseudo-terminal as it would in a lab, against the simulated rig
served on another pty (wall clock); the experimenter reads the prompts, acts on the rig
through its operator hooks, or fails to, and types on the terminal.
"""

from __future__ import annotations

import math
import os
import sys
from pathlib import Path

import pytest

pexpect = pytest.importorskip("pexpect", reason="pip install pexpect (the test extras)")

from test_acquire_pty import REVIEW, quick_protocol, rig_on_pty  # noqa: E402,F401 (a fixture)

from labcli.papers.takuma2014.records import load_trials  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
# Seven trials teach the session what a load does on this rig (by trial 8 it is sure that 1000 g
# at -30 deg bends the lower joint by at least 8 deg); trial 8 is the one the experimenter never
# loads, trial 9 the one whose weight is left hanging.
LEARN = ((800, -60), (800, 30), (800, 150), (800, -150), (1000, -60), (800, -90), (800, 90))
PLAN = (
    "trial,set,mass_g,direction_deg\n"
    + "".join(f"{i},fit,{m},{d}\n" for i, (m, d) in enumerate(LEARN, 1))
    + "8,validation,1000,-30\n9,validation,800,-60\n10,validation,500,150\n"
)


def spawn(args: list[str]) -> pexpect.spawn:
    env = dict(os.environ, COLUMNS="300", PYTHONUNBUFFERED="1")
    child = pexpect.spawn(
        sys.executable,
        ["-m", "labcli", "acquire", *args],
        cwd=str(ROOT),
        env=env,
        encoding="utf-8",
        timeout=30,
        dimensions=(50, 300),
    )
    return child


def setup(child, rig) -> None:
    child.expect_exact("Supply compressed air to the four actuators, then press Enter (q to quit):")
    rig.supply_air()
    child.sendline("")
    child.expect_exact("Close the valves so that the actuators are sealed, then press Enter (q to quit):")
    rig.close_valves()
    child.sendline("")


def trial(child, rig, label: str, mass_g: float, direction_deg: float, *, hang=True, remove=True) -> None:
    child.expect_exact(f"{label}: hang {mass_g:g} g, pulley direction {direction_deg:g} deg, then press Enter")
    if hang:
        rig.hang_weight(mass_g * 1e-3, math.radians(direction_deg))
    child.sendline("")
    child.expect_exact(f"{label}: remove the weight, then press Enter")
    if remove:
        rig.remove_weight()
    child.sendline("")


def test_enter_twice_without_the_weight_never_stores_the_trial_and_a_weight_left_on_is_warned(tmp_path, rig_on_pty):
    rig = rig_on_pty.rig
    proto = quick_protocol(tmp_path)
    (tmp_path / "plan.csv").write_text(PLAN)
    run = tmp_path / "run.h5"
    child = spawn([str(run), "--port", rig_on_pty.path, "--protocol", str(proto), "--plan", str(tmp_path / "plan.csv")])
    setup(child, rig)
    for i, (mass, direction) in enumerate(LEARN, start=1):
        trial(child, rig, f"Trial {i}/10 (fit)", mass, direction)
        child.expect_exact(REVIEW)
        child.sendline("a")

    # Trial 8: Enter pressed twice at "hang", no weight hung. The second Enter was typed ahead of the
    # "remove" prompt and is discarded there; the review warns and defaults to redo.
    child.expect_exact("Trial 8/10 (validation): hang 1000 g, pulley direction -30 deg, then press Enter")
    child.send("\r\r")
    child.expect_exact("Trial 8/10 (validation): remove the weight, then press Enter")
    child.sendline("")
    child.expect(
        "check that the load was applied as the prompt said, then redo the trial \\(Enter\\), or accept it "
        "as it is \\(a\\)"
    )
    child.expect_exact("Accept [a], redo [r], skip [s], note [n] or quit [q]? (r):")
    child.sendline("")  # Enter alone: the default, redo
    trial(child, rig, "Trial 8/10 (validation)", 1000, -30)
    child.expect_exact(REVIEW)
    child.sendline("a")

    # Trial 9: the weight is left hanging; trial 10's baseline shows it and the session says so.
    trial(child, rig, "Trial 9/10 (validation)", 800, -60, remove=False)
    child.expect_exact(REVIEW)
    child.sendline("a")
    child.expect(
        "The readings have not returned since the last load: they are still \\d+% of the way to the loaded ones"
    )
    child.expect_exact("the last weight may still hang on the pulley")
    rig.remove_weight()
    child.sendline("")
    trial(child, rig, "Trial 10/10 (validation)", 500, 150)
    child.expect_exact(REVIEW)
    child.sendline("a")
    child.expect_exact("Session complete: 10 trials stored")
    child.expect(pexpect.EOF)
    child.close()
    assert child.exitstatus == 0
    df = load_trials(run).set_index("trial")
    # Trial 8 as stored is the redone one: the lower joint bent under the 1000 g as far as under
    # the same weight at -60 deg within a factor of two (0 deg had it been stored unloaded).
    assert abs(df.loc[8, "theta1_deg"]) > 0.5 * abs(df.loc[5, "theta1_deg"]) > 0.5


def quick_push_protocol(tmp_path: Path, pushes: int) -> Path:
    """The shipped stiffness protocol with the quick settling window of ``quick_protocol``, a short
    capture and ``pushes`` pushes per object (the shipped 5 s earliest acceptance is not under test)."""
    import re

    from labcli.core.protocol import load_protocol

    text = load_protocol("takuma2014-stiffness").text
    for key, value in (
        ("window_s", "0.2"),
        ("hold_s", "0.2"),
        ("timeout_s", "20.0"),
        ("capture_s", "0.2"),
        ("pressure_spread_MPa", "0.001"),
        ("angle_spread_deg", "0.3"),
        ("pushes_per_object", str(pushes)),
    ):
        text, n = re.subn(rf"(?m)^{key} = .*$", f"{key} = {value}", text)
        assert n == 1
    text, n = re.subn(r"(?m)^rate_hz = .*$", lambda m: m.group(0) + '\nvalves = "hand"', text)  # the person's valves
    assert n == 1
    path = tmp_path / "push.toml"
    path.write_text(text)
    return path


class Typist:
    """Types answers on the terminal and counts them, per push."""

    def __init__(self, child) -> None:
        self.child = child
        self.count = 0

    def answer(self, prompt: str, text: str = "") -> None:
        self.child.expect_exact(prompt)
        self.child.sendline(text)
        self.count += 1


def test_a_two_object_push_session_asks_per_push_at_most_three_answers(tmp_path, rig_on_pty):
    rig = rig_on_pty.rig
    pushes = 3
    proto = quick_push_protocol(tmp_path, pushes)
    run = tmp_path / "push.h5"
    child = spawn([str(run), "--port", rig_on_pty.path, "--protocol", str(proto)])
    t = Typist(child)
    child.expect_exact("Supply compressed air to the four actuators, then press Enter (q to quit):")
    rig.supply_air()
    t.answer("")
    child.expect_exact("then press Enter (q to quit):")
    rig.close_valves()
    t.answer("")
    objects = (
        ("pet-1", "33", "soft", "10", "30", 0.033, 0.010, 30.0, 300.0),
        ("can-2", "40", "hard", "", "", 0.040, 0.010, 30.0, 3000.0),
    )  # Enter keeps pet-1's d and phi
    per_push = []
    for i, (name, r_mm, cat, d_mm, phi, R, d, phi_deg, k) in enumerate(objects, start=1):
        t.answer(f"Object {i}: name", name)
        t.answer(f"{name}: radius R in mm:", r_mm)
        t.answer(f"{name}: category", cat)
        t.answer(f"{name}: push distance d in mm for its pushes", d_mm)
        t.answer(f"{name}: push direction phi in deg for its pushes", phi)
        for j in range(1, pushes + 1):
            before = t.count
            child.expect_exact(f"Push {j}/{pushes} of {name}: push {name} by 10 mm along 30 deg, then press Enter")
            rig.push_object(R, d, math.radians(phi_deg), k)
            t.answer("(q to quit):")
            child.expect_exact(f"Push {j}/{pushes} of {name}: move {name} back until it just touches")
            rig.release_object()
            t.answer("(q to quit):")
            t.answer(REVIEW)
            per_push.append(t.count - before)
    t.answer("Object 3: name")  # Enter: all objects done
    child.expect_exact(f"Session complete: {2 * pushes} ")
    child.expect(pexpect.EOF)
    child.close()
    assert child.exitstatus == 0
    # Per object five answers; per push at most three (the push, the release, the review).
    assert max(per_push) <= 3
    assert t.count == 2 + 2 * 5 + 2 * pushes * 3 + 1
    from labcli.papers.takuma2014.records import load_pushes

    df = load_pushes(run)
    assert df["object"].tolist() == ["pet-1"] * pushes + ["can-2"] * pushes
    assert df["R_m"].tolist() == pytest.approx([0.033] * pushes + [0.040] * pushes)
    assert df["d_m"].tolist() == pytest.approx([0.010] * (2 * pushes))
