"""The ``labcli`` command line.

Each subcommand lives in ``labcli/commands/<name>.py`` and is imported only
when it runs, so ``labcli --help`` loads click and nothing heavy.  Commands are
thin: parse, call the library once, turn :class:`~labcli.errors.LabcliError`
into a one-line :class:`click.ClickException`.
"""

from __future__ import annotations

import codecs
import errno
import importlib
import io
import os
import signal
import sys
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
    elif sys.warnoptions:  # asked for (python -W, PYTHONWARNINGS): shown as Python shows them
        _python_show_warning(message, category, filename, lineno, file, line)
    # otherwise a library's warning (numpy's overflow on an absurd rig option) is no sentence for
    # the person at the rig: what it means reaches them as the command's own check


def _text_errors(err: UnicodeError) -> tuple[str | bytes, int]:
    """What a stream cannot encode: a file name's raw bytes back as they were (Python keeps them
    as lone surrogates; ``ls`` shows them so), anything else as a ``\\u00b0`` escape; never a traceback."""
    if isinstance(err, UnicodeEncodeError):
        bad = err.object[err.start : err.end]
        if all("\udc80" <= c <= "\udcff" for c in bad):
            return bad.encode("utf-8", "surrogateescape"), err.end
    return codecs.backslashreplace_errors(err)


class OutputUnwritable(Exception):
    """Standard output refused a write (a full disk or /dev/full, a closed pipe's end)."""

    def __init__(self, strerror: str) -> None:
        super().__init__(strerror)
        self.strerror = strerror


class _GuardedOutput(io.RawIOBase):
    """Standard output's descriptor, whose failed write stops the command in one sentence; the
    bytes still buffered after that are dropped instead of failing again at exit."""

    def __init__(self, fd: int) -> None:
        super().__init__()
        self._fd = fd
        self.failed = False

    def writable(self) -> bool:
        return True

    def fileno(self) -> int:
        return self._fd

    def isatty(self) -> bool:
        return os.isatty(self._fd)

    def write(self, data) -> int:  # noqa: ANN001 - a bytes-like object, as RawIOBase.write takes
        if self.failed:
            return len(data)
        try:
            return os.write(self._fd, data)
        except OSError as e:
            self.failed = True
            raise OutputUnwritable(e.strerror or str(e)) from None


def _guard_streams() -> None:
    codecs.register_error("labcli-text", _text_errors)
    for stream in (sys.stdout, sys.stderr):
        if isinstance(stream, io.TextIOWrapper):
            stream.reconfigure(errors="labcli-text")
    out = sys.stdout
    if isinstance(out, io.TextIOWrapper) and out.fileno() == 1:
        out.flush()
        sys.stdout = io.TextIOWrapper(
            io.BufferedWriter(_GuardedOutput(1)),
            encoding=out.encoding,
            errors="labcli-text",
            line_buffering=out.line_buffering or out.isatty(),
        )


def _as_interrupt(signum: int, frame: object) -> None:
    """SIGTERM and SIGHUP (a closed terminal, a stopping service) end a command as Ctrl-C does:
    an acquisition stores what is whole, records how its session ended and says how to resume."""
    raise KeyboardInterrupt


MIN_ADDRESS_SPACE_MIB = 448  # numpy, pandas, h5py and OpenBLAS's buffers: 342 MiB failed to load them, 488 MiB ran


def _check_address_space() -> None:
    """One sentence, before anything is read or written, when ``ulimit -v`` leaves too little to load
    the libraries (they fail to load as ImportError, OpenBLAS's own abort or a segfault)."""
    try:
        import resource

        soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    except (ImportError, OSError, ValueError):
        return
    if soft != resource.RLIM_INFINITY and soft < MIN_ADDRESS_SPACE_MIB * 2**20:
        click.echo(
            f"Error: the address-space limit (ulimit -v) is {soft // 2**20} MiB, below the "
            f"{MIN_ADDRESS_SPACE_MIB} MiB labcli needs to load numpy, pandas and HDF5; raise it "
            "(ulimit -v unlimited) and run the command again. Nothing was read or written.",
            err=True,
        )
        sys.exit(1)


MIN_OPEN_FILES = 32  # a run file and its journal, the rig's port, a figure's fonts: validate --plot needed 10


def _open_files_limit() -> int | None:
    """The soft limit on open files (``ulimit -n``), or None when there is none to read."""
    try:
        import resource

        soft, _ = resource.getrlimit(resource.RLIMIT_NOFILE)
    except (ImportError, OSError, ValueError):
        return None
    return None if soft == resource.RLIM_INFINITY else int(soft)


def _check_open_files() -> None:
    """One sentence, before anything is read or written, when ``ulimit -n`` leaves too few files:
    a figure's fonts or a run's journal would fail half-way, after a model file was written."""
    soft = _open_files_limit()
    if soft is not None and soft < MIN_OPEN_FILES:
        click.echo(
            f"Error: the open-file limit (ulimit -n) is {soft}, below the {MIN_OPEN_FILES} files labcli may "
            "hold open at once (a run file and its journal, the rig's port, a figure's fonts); raise it "
            "(ulimit -n 1024) and run the command again. Nothing was read or written.",
            err=True,
        )
        sys.exit(1)


def _out_of_files(e: BaseException) -> None:
    """Past the check above, a command that still ran out of open files (EMFILE, or the system's
    table full, ENFILE) ends in one sentence naming the limit, not in a traceback or a damaged run."""
    text = str(e)
    if not isinstance(e, OSError) or not (
        e.errno in (errno.EMFILE, errno.ENFILE) or "Too many open files" in text or "errno = 24" in text
    ):
        return
    limit = _open_files_limit()
    click.echo(
        f"Error: labcli ran out of open files (the open-file limit, ulimit -n, is "
        f"{'unlimited' if limit is None else limit}); raise it (ulimit -n 1024) and run the command again.",
        err=True,
    )
    sys.exit(1)


def main() -> None:
    warnings.showwarning = _show_warning
    _check_address_space()
    _check_open_files()
    for name in ("SIGTERM", "SIGHUP"):
        if hasattr(signal, name):
            signal.signal(getattr(signal, name), _as_interrupt)
    try:
        _guard_streams()
    except (OSError, ValueError):
        pass  # streams of an embedding program: left as they are
    try:
        cli(prog_name="labcli", obj={"own_process": True})
    except Exception as e:
        if isinstance(e, OutputUnwritable):
            _output_unwritable(e)
        _out_of_files(e)
        if not isinstance(e, (OSError, RuntimeError, KeyError)) or not _from_hdf5(e):
            raise
        why = str(e).strip("'\"").split(" (")[0] or type(e).__name__
        click.echo(
            f"Error: a run file is damaged and HDF5 cannot read part of it ({why}); check it with "
            "labcli inspect --verify, and use a backup copy.",
            err=True,
        )
        sys.exit(1)
    finally:
        # The command has ended in its own words: a Ctrl-C while the interpreter then shuts down
        # could only print a stray "Exception ignored ... KeyboardInterrupt" from its clean-up.
        signal.signal(signal.SIGINT, signal.SIG_IGN)


def _from_hdf5(e: BaseException) -> bool:
    """Whether ``e`` came out of h5py reading a file (a damaged one: labcli's own errors are sentences)."""
    tb = e.__traceback__
    while tb is not None:
        if "h5py" in tb.tb_frame.f_code.co_filename.replace("\\", "/").split("/"):
            return True
        tb = tb.tb_next
    return False


def _output_unwritable(e: OutputUnwritable) -> None:
    click.echo(
        f"Error: standard output cannot take what labcli writes ({e.strerror}); send it to a file "
        "on a disk with room, or to the terminal.",
        err=True,
    )
    sys.exit(1)
