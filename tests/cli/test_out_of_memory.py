"""Memory running out mid-acquisition (a MemoryError: numpy's buffers, HDF5's chunk cache, under a
tight ``ulimit -v`` or a full machine) ends ``labcli acquire`` in one sentence with the resume line;
the trials committed before are whole, the run verifies, and resuming completes it."""

from __future__ import annotations

import pytest
from click.testing import CliRunner

from labcli.cli import cli
from labcli.core.engine import RunEngine
from labcli.core.store import RunFile
from labcli.core.store.columns import Table
from labcli.core.store.verify import verify
from labcli.papers.takuma2014.records import load_trials
from labcli.papers.takuma2014.session import Capture

PORT = "sim://?seed=3&clock=virtual"
PLAN = "trial,set,mass_g,direction_deg\n1,fit,200,-60\n2,fit,500,30\n3,validation,300,150\n4,validation,400,-150\n"


def in_capture(monkeypatch) -> None:
    """Trial 3's loaded capture cannot get the memory it asks for."""
    execute = RunEngine._execute

    def short_of_memory(self, step):
        if isinstance(step, Capture) and self._trial is not None and self._trial.trial == 3:
            raise MemoryError
        return execute(self, step)

    monkeypatch.setattr(RunEngine, "_execute", short_of_memory)


def in_hdf5_write(monkeypatch) -> None:
    """Trial 3's rows are half-written into the file when HDF5 cannot get the memory it asks for."""
    write = Table.write
    rows = []

    def short_of_memory(self, arrays, n):
        span = write(self, arrays, n)
        if self.g.name.endswith("/trials"):
            rows.append(span)
            if len(rows) == 3:
                raise MemoryError
        return span

    monkeypatch.setattr(Table, "write", short_of_memory)


@pytest.mark.parametrize("where", [in_capture, in_hdf5_write], ids=lambda f: f.__name__)
def test_memory_running_out_mid_acquisition_is_one_sentence_and_the_run_resumes(tmp_path, monkeypatch, where):
    path = tmp_path / "run.h5"
    plan = tmp_path / "plan.csv"
    plan.write_text(PLAN)
    args = ["acquire", str(path), "--port", PORT, "--unattended", "--plan", str(plan)]
    where(monkeypatch)
    result = CliRunner().invoke(cli, args)
    assert result.exit_code == 1, result.output
    assert result.output.splitlines()[-1] == (
        f"Error: Memory ran out during trial 3, which was not stored; the 2 completed trials in {path} are "
        f"unchanged. Close other programs (or raise ulimit -v), then resume with: "
        f"labcli acquire {path} --port '{PORT}' --resume --unattended"
    )
    assert "Traceback" not in result.output and "MemoryError" not in result.output
    monkeypatch.undo()
    with RunFile.open(path) as run:
        report = verify(run)
        # The session log says so, unless HDF5 itself ran short mid-write (nothing more is written then).
        assert run.sessions.all()[-1]["how"] == ("out of memory" if where is in_capture else None)
    assert report["ok"], report["problems"]
    assert report["records"] == 2
    assert load_trials(path)["trial"].tolist() == [1, 2]
    resumed = CliRunner().invoke(cli, ["acquire", str(path), "--port", PORT, "--resume", "--unattended"])
    assert resumed.exit_code == 0, resumed.output
    assert load_trials(path)["trial"].tolist() == [1, 2, 3, 4]
