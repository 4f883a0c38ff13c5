"""The ``labcli`` command line.

Each subcommand lives in ``labcli/commands/<name>.py`` and is imported only
when it runs, so ``labcli --help`` loads click and nothing heavy.  Commands are
thin: parse, call the library once, turn :class:`~labcli.errors.LabcliError`
into a one-line :class:`click.ClickException`.
"""

from __future__ import annotations

import importlib
import signal
import warnings

import click

from . import __version__

# name -> (module, attribute, one-line help shown by ``labcli --help``)
COMMANDS: dict[str, tuple[str, str, str]] = {
    "demo": ("labcli.commands.demo", "demo", "Run the whole paper on the simulated rig, no hardware needed."),
    "acquire": ("labcli.commands.acquire", "acquire", "Guide a run at the rig and record it into an HDF5 file."),
    "fit": ("labcli.commands.fit", "fit", "Fit the paper's regression (Eqs. 34-37) to a run's fit trials."),
    "validate": ("labcli.commands.validate", "validate", "Check a fitted model on the validation trials (Figure 7)."),
    "predict": ("labcli.commands.predict", "predict", "Estimate angles and forces for new data with a fitted model."),
    "sense": ("labcli.commands.sense", "sense", "Estimate angles and forces live from a rig's pressures."),
    "classify": (
        "labcli.commands.classify",
        "classify",
        "Object stiffness and material category from pushes (Section 4).",
    ),
    "optimize": ("labcli.commands.optimize", "optimize", "Optimise an rPAM joint's link lengths for joint travel."),
    "split": ("labcli.commands.split", "split", "Assign a run's trials to the fit and validation sets."),
    "inspect": ("labcli.commands.inspect", "inspect", "Summarise a run file: trials, split, completeness, drift."),
    "runs": (
        "labcli.commands.runs",
        "runs",
        "List the run files under a folder: uid, protocol, rig, trials, split, status.",
    ),
    "note": ("labcli.commands.note", "note", "Keep a note about a run or one of its trials in the run file."),
    "export": ("labcli.commands.export", "export", "Write a run's trial or push table as CSV."),
    "import": ("labcli.commands.import_", "import_", "Build a run file from a trial or push CSV table."),
    "monitor": ("labcli.commands.monitor", "monitor", "Show live calibrated readings and link statistics."),
    "ports": ("labcli.commands.ports", "ports", "List the serial ports and which board each looks like."),
    "flash": ("labcli.commands.flash", "flash", "Write the rig firmware onto a board with avrdude."),
    "export-model": (
        "labcli.commands.export_model",
        "export_model",
        "Write a fitted model as C for the rig firmware (estimates on the chip).",
    ),
    "sim": ("labcli.commands.sim", "sim", "Serve the simulated rig on a pseudo-terminal."),
}


class LazyGroup(click.Group):
    """A group whose subcommands are imported on first use."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        return list(COMMANDS)

    def get_command(self, ctx: click.Context, name: str) -> click.Command | None:
        entry = COMMANDS.get(name)
        if entry is None:
            return None
        module, attr, _ = entry
        return getattr(importlib.import_module(module), attr)

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        # Short help comes from the table so that --help imports no command module.
        rows = [(name, short) for name, (_, _, short) in COMMANDS.items()]
        with formatter.section("Commands"):
            formatter.write_dl(rows)


@click.group(cls=LazyGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, "-V", "--version", prog_name="labcli")
def cli() -> None:
    """Lab acquisition for pneumatic-actuator rigs.

    \b
    Try it with no hardware:
        labcli demo out/
    Talk to a rig (or the simulated one):
        labcli monitor --port sim:// --seconds 5
    """


_python_show_warning = warnings.showwarning


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:  # noqa: ANN001
    """A LabcliWarning (a damaged record left out, ...) is one line for the user; others as Python shows them."""
    from .errors import LabcliWarning

    if issubclass(category, LabcliWarning):
        click.echo(f"Warning: {message}", err=True)
    else:
        _python_show_warning(message, category, filename, lineno, file, line)


def main() -> None:
    warnings.showwarning = _show_warning
    try:
        cli(prog_name="labcli", obj={"own_process": True})
    finally:
        # The command has ended in its own words: a Ctrl-C while the interpreter then shuts down
        # could only print a stray "Exception ignored ... KeyboardInterrupt" from its clean-up.
        signal.signal(signal.SIGINT, signal.SIG_IGN)
