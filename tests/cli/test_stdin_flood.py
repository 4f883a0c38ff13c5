"""Attended acquisition with a standard input that floods bytes and never ends a line (``</dev/zero``).

It died with MemoryError (``input()`` reading an endless line).  An answer is read with a bound
(:data:`labcli.core.ui.MAX_ANSWER_CHARS`); beyond it the session ends as when input ends: one
sentence, the trials before it stored, the run verifies and resumes.
"""

from __future__ import annotations

from pathlib import Path

from support.procs import labcli

from labcli.core.ui import MAX_ANSWER_CHARS

PLAN = "trial,set,mass_g,direction_deg\n1,fit,300,-60\n2,fit,500,30\n3,validation,400,120\n"
PORT = "sim://?seed=1&clock=virtual"


def test_a_flood_on_standard_input_ends_in_one_sentence_and_loses_nothing(tmp_path: Path) -> None:
    (tmp_path / "plan.csv").write_text(PLAN)
    # Enter for every question of trial 1 (a hang prompt and the review take one each; spares are
    # read by the next questions), then bytes with no line end, as /dev/zero gives.
    feed = tmp_path / "feed"
    feed.write_bytes(b"\n" * 5 + b"\0" * (MAX_ANSWER_CHARS * 4))
    r = labcli("acquire", "r.h5", "--port", PORT, "--plan", "plan.csv", cwd=tmp_path, stdin=feed)
    assert "Traceback" not in r.stderr and "MemoryError" not in r.stderr
    assert r.returncode == 1
    last = r.stderr.strip().splitlines()[-1]
    assert last.startswith(
        "Error: No input: standard input sent more than 4096 characters with no line end, as a device such "
        "as /dev/zero does, at a question during trial "
    ), last
    assert last.endswith(f"Resume where someone at the rig can answer: labcli acquire r.h5 --port '{PORT}' --resume")
    stored = int(last.split("; ")[1].split()[0])
    assert stored >= 1  # trial 1 answered: kept
    v = labcli("inspect", "r.h5", "--verify", cwd=tmp_path)
    assert v.returncode == 0, v.stderr
    assert f"{stored} trial" in v.stdout
    resumed = labcli("acquire", "r.h5", "--port", PORT, "--resume", "--unattended", cwd=tmp_path)
    assert resumed.returncode == 0, resumed.stderr
    assert "Session complete: 3 trials stored in r.h5" in resumed.stdout + resumed.stderr
