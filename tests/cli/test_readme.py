"""The README and docs/ are what a new user reads first: their commands must work as written.

The README is the door (the two commands, the demo, the commands table); the topics live in
docs/<topic>.md.  Every ``labcli ...`` command those pages show names a real command and real
options; the ones that run on the simulated rig or the sample runs are run; every link and
image points at a file (and heading) that exists.
"""

from __future__ import annotations

import re
import shlex
import subprocess
import sys
from pathlib import Path

import click
import pytest

from labcli.cli import cli

ROOT = Path(__file__).resolve().parents[2]
README = (ROOT / "README.md").read_text(encoding="utf-8")
PAGES = {
    p.relative_to(ROOT).as_posix(): p.read_text(encoding="utf-8")
    for p in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
}
# Pages outside docs/ that the docs link to and that link back.
OTHER_PAGES = ["firmware/README.md", "tests/benchmarks/README.md", "CHANGELOG.md"]

# The suite on every core, a module per worker (its module-scoped simulated runs made once),
# with each skip's reason listed.
TEST_COMMAND = "pip install '.[test]' && python -m pytest -q -rs -n auto --dist loadscope"
MAX_README_LINES = 400


def code_blocks(lang: str, text: str = README) -> list[str]:
    return re.findall(rf"^```{lang}\n(.*?)^```", text, flags=re.S | re.M)


def all_blocks(lang: str) -> list[tuple[str, str]]:
    return [(page, b) for page, text in PAGES.items() for b in code_blocks(lang, text)]


def test_readme_is_a_door():
    assert len(README.splitlines()) <= MAX_README_LINES
    # The README leads to the docs index's topics.
    index = (ROOT / "docs" / "README.md").read_text(encoding="utf-8")
    for name in re.findall(r"\]\(([\w-]+\.md)\)", index):
        if name != "README.md":
            assert f"](docs/{name})" in README, f"the README does not link docs/{name}"


def test_top_two_commands_install_and_run_demo_and_tests():
    top = README[: README.index("## A tour")]
    assert "pip install . && labcli demo out/demo" in top
    assert f"{TEST_COMMAND}\n" in top


def test_ci_runs_exactly_the_readme_test_command():
    # The same extraction .ci/run performs.
    awk = r"""/<!-- readme-test-command -->/{getline; while ($0 !~ /^[a-z]/) getline; print; exit}"""
    out = subprocess.run(["awk", awk, "README.md"], cwd=ROOT, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == TEST_COMMAND
    assert "awk '/<!-- readme-test-command -->/" in (ROOT / ".ci" / "run").read_text()


def test_python_example_runs_and_predicts_the_stored_angles():
    (code,) = [b for b in code_blocks("python") if "load_trials" in b]
    env: dict = {}
    exec(compile(code, "README.md", "exec"), env)  # noqa: S102 - the README's own example
    import numpy as np

    trials, pred = env["trials"], env["pred"]
    err = np.degrees(pred["theta1_rad"]) - trials["theta1_deg"].to_numpy()
    # deg: the sample run comes from the default (realistic) rig, whose 0.2 deg potentiometer play
    # and sleeve friction put the angles' error near 0.14 deg; a broken example is off by degrees.
    assert np.sqrt(np.mean(err**2)) < 0.25


# ----------------------------------------------------------------------------- commands shown


def shell_commands() -> list[tuple[str, str]]:
    """(page, command) for every ``labcli`` line of a shell block, comments stripped."""
    out = []
    for page, block in all_blocks("sh"):
        for line in block.splitlines():
            cmd = line.split("  #", 1)[0].strip()
            if cmd.startswith("labcli "):
                out.append((page, cmd))
    return out


def inline_commands() -> list[tuple[str, str]]:
    """(page, command) for every inline ``labcli ...`` code span in the prose."""
    out = []
    for page, text in PAGES.items():
        prose = re.sub(r"^```.*?^```", "", text, flags=re.S | re.M)
        for span in re.findall(r"`(labcli [^`]+)`", prose.replace("\n", " ")):
            out.append((page, " ".join(span.split())))
    return out


def _command(args: list[str]) -> click.Command:
    with click.Context(cli) as ctx:
        cmd = cli.get_command(ctx, args[0])
    assert cmd is not None, f"no command {args[0]!r}"
    return cmd


def _option_names(cmd: click.Command) -> set[str]:
    # get_params: a command's own options and those the papers declare for it (labcli.core.options).
    with click.Context(cmd) as ctx:
        params = cmd.get_params(ctx)
    return {o for p in params for o in (*p.opts, *p.secondary_opts)}


@pytest.mark.parametrize("page, cmd", shell_commands(), ids=lambda x: x[:60] if isinstance(x, str) else None)
def test_every_shell_command_parses(page, cmd):
    """A command a page tells people to type is accepted by the CLI as it is today."""
    args = shlex.split(cmd)[1:]
    command = _command(args)
    try:
        command.make_context(args[0], args[1:])
    except click.exceptions.Exit:
        pass
    except click.UsageError as e:
        pytest.fail(f"{page}: `{cmd}` does not parse: {e.format_message()}")


def test_every_inline_command_names_real_options():
    """``labcli CMD ... --opt`` in the prose: the command exists and has each option shown."""
    spans = inline_commands()
    assert len(spans) > 30
    bad = []
    for page, span in spans:
        words = span.split()
        if len(words) < 2 or not re.fullmatch(r"[a-z]+", words[1]):
            continue  # `labcli --help`, `labcli --version`
        command = _command(words[1:])
        known = _option_names(command)
        for w in words[2:]:
            opt = w.split("=", 1)[0].rstrip(",.;)")
            if re.fullmatch(r"--?[a-zA-Z][\w-]*", opt) and opt not in known:
                bad.append(f"{page}: `{span}`: {opt}")
    assert not bad, "\n".join(bad)


def test_plan_prompts_shown_match_the_shipped_plan():
    """A `Trial N/108 (set): hang M g, pulley direction D deg` line is the plan's row N."""
    import pandas as pd

    plan = pd.read_csv(ROOT / "protocols" / "takuma2014-plan.csv").set_index("trial")
    shown = [
        m
        for text in PAGES.values()
        for m in re.finditer(r"Trial (\d+)/108 \((\w+)\): hang (\d+) g, pulley direction (-?\d+) deg", text)
    ]
    assert shown
    for m in shown:
        row = plan.loc[int(m.group(1))]
        assert (row["set"], row["mass_g"], row["direction_deg"]) == (m.group(2), int(m.group(3)), int(m.group(4))), (
            m.group(0)
        )


# ----------------------------------------------------------------------------- commands run


def runnable_blocks() -> list[list[str]]:
    """Shell blocks that run on the simulated rig or the sample runs (no hardware, no waiting)."""
    blocks = []
    for _, block in all_blocks("sh"):
        if "--unattended" not in block and "sample_runs/" not in block:
            continue
        lines = []
        for line in block.splitlines():
            cmd = line.split("#", 1)[0].strip() if not line.strip().startswith("labcli sim") else ""
            if cmd.startswith("labcli ") and " monitor " not in f" {cmd} " and "--pty" not in cmd:
                lines.append(cmd)
            elif cmd.startswith("mkdir -p ") and lines == []:
                lines.append(cmd)
        if lines:
            blocks.append(lines)
    return blocks


def outputs(cmd: str) -> list[str]:
    args = shlex.split(cmd)
    return [args[i + 1] for i, a in enumerate(args[:-1]) if a in ("-o", "--plot")] + (
        [args[2]] if args[1] == "acquire" else []
    )


@pytest.mark.parametrize("block", runnable_blocks(), ids=lambda b: b[1][:40] if len(b) > 1 else b[0][:40])
def test_shell_blocks_run_as_written(block, tmp_path):
    sample = ROOT / "sample_runs"
    before = {p.name: p.read_bytes() for p in sample.iterdir()}
    for cmd in block:
        if cmd.startswith("mkdir -p "):
            (tmp_path / cmd.split()[2]).mkdir(parents=True)
            continue
        args = shlex.split(cmd.replace("sample_runs/", f"{sample}/"))
        r = subprocess.run(
            [sys.executable, "-m", "labcli", *args[1:]], cwd=tmp_path, capture_output=True, text=True, timeout=300
        )
        assert r.returncode == 0, (cmd, r.stdout[-2000:], r.stderr[-2000:])
        assert "Traceback" not in r.stderr
        for out in outputs(cmd):
            assert (tmp_path / out).stat().st_size > 0, (cmd, out)
    # Trying the samples never changes them.
    assert {p.name: p.read_bytes() for p in sample.iterdir()} == before


def test_there_are_runnable_blocks():
    cmds = [c for b in runnable_blocks() for c in b]
    assert any("acquire" in c and "--unattended" in c for c in cmds)
    assert any(c.startswith("labcli fit sample_runs/") for c in cmds)
    assert any("rpam2015" in c for c in cmds)


def test_example_outputs_stay_in_one_ignored_folder():
    # Every file an example writes lands under out/, which .gitignore covers.
    written = [o for _, cmd in shell_commands() for o in outputs(cmd)]
    assert written and all(o.startswith("out/") for o in written), written
    assert "/out/" in (ROOT / ".gitignore").read_text().split()


# ----------------------------------------------------------------------------- links


def slug(heading: str) -> str:
    """GitHub's anchor for a heading: lower case, punctuation dropped, spaces to hyphens."""
    text = re.sub(r"[`*_]|<[^>]+>", "", heading.strip()).lower()
    return re.sub(r"[^\w\- ]", "", text).replace(" ", "-")


def anchors(text: str) -> set[str]:
    text = re.sub(r"^```.*?^```", "", text, flags=re.S | re.M)
    return {slug(h) for h in re.findall(r"^#{1,6} (.+)$", text, flags=re.M)}


def links() -> list[tuple[str, str]]:
    out = []
    for page in [*PAGES, *OTHER_PAGES]:
        path = ROOT / page
        if not path.is_file():
            continue
        text = re.sub(r"^```.*?^```", "", path.read_text(encoding="utf-8"), flags=re.S | re.M)
        text = re.sub(r"`[^`\n]*`", "", text)
        out += [(page, target) for target in re.findall(r"\]\(([^)\s]+)\)", text)]
    return out


def test_links_and_images_resolve():
    found, bad = links(), []
    assert len(found) > 50
    for page, target in found:
        if re.match(r"[a-z]+:", target):
            continue  # https:, mailto:
        file, _, anchor = target.partition("#")
        dest = (ROOT / page).parent / file if file else ROOT / page
        if not dest.resolve().is_relative_to(ROOT) or not dest.exists():
            bad.append(f"{page}: {target}: no such file")
        elif anchor and dest.suffix == ".md" and anchor not in anchors(dest.read_text(encoding="utf-8")):
            bad.append(f"{page}: {target}: no heading with that anchor")
    assert not bad, "\n".join(bad)


def test_slug_known_answers():
    assert (
        slug("Fit and validate (Sections 2.2.4, 3.2, 3.3; Figure 7)") == "fit-and-validate-sections-224-32-33-figure-7"
    )
    assert slug("The posture-aware form (the default)") == "the-posture-aware-form-the-default"
    assert slug("At the rig: `labcli acquire`") == "at-the-rig-labcli-acquire"


def test_docs_cited_by_the_code_exist_and_are_linked():
    cited = set()
    for path in [*(ROOT / "labcli").rglob("*.py"), *(ROOT / "protocols").glob("*.toml")]:
        cited.update(re.findall(r"docs/[\w-]+\.md", path.read_text(encoding="utf-8")))
    assert cited, "the code cites no docs"
    index = (ROOT / "docs" / "README.md").read_text(encoding="utf-8")
    for doc in cited | {"docs/wire-protocol.md", "docs/table-formats.md", "docs/errata.md"}:
        assert (ROOT / doc).is_file(), doc
        assert f"]({doc})" in README or f"]({Path(doc).name})" in index, f"{doc} is not linked"


def test_error_messages_shown_are_the_ones_labcli_prints():
    """Each `Error: ...` line a page shows is one the bad-input table records (and so a test runs)."""
    table = (ROOT / "tests" / "bad_input_table.md").read_text(encoding="utf-8")
    shown = [
        line.strip()
        for _, block in all_blocks("text")
        for line in block.splitlines()
        if line.startswith("Error: ") and not line.startswith("Error: bad.csv has")
    ]
    assert len(shown) >= 3
    for line in shown:
        assert line in table, line
