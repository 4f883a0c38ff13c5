"""Child processes of the tests: ``labcli`` run as people run it, and what a child wrote, once it has ended."""

from __future__ import annotations

import os
import resource
import signal
import subprocess
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import IO


def labcli(
    *args: str,
    cwd: Path,
    stdin: str | os.PathLike | None = None,
    timeout: float = 120,
    env: Mapping[str, str] | None = None,
    limits: Mapping[int, int] | None = None,
    errors: str | None = None,
    stdout: int | IO[str] = subprocess.PIPE,
) -> subprocess.CompletedProcess:
    """``python -m labcli ARGS`` in ``cwd``, its output captured as text.

    ``COLUMNS=400``, so that no sentence a test matches is wrapped; ``stdin``: a file read as
    standard input (none: an empty one); ``env``: variables set beside the environment's;
    ``limits``: resource limits set in the child (``resource.RLIMIT_FSIZE``: bytes, as ``ulimit -f``
    sets them, with SIGXFSZ ignored as a shell leaves it; ``RLIMIT_NOFILE``: open files, as
    ``ulimit -n``); ``errors``: how the output is decoded (``"surrogateescape"`` keeps the bytes of a
    file name that is not UTF-8 as the child wrote them; none: strict); ``stdout``: where standard
    output goes (a file: not captured, as ``>/dev/full`` sends it), standard error captured always.
    """

    def preexec() -> None:
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        for which, value in (limits or {}).items():
            resource.setrlimit(which, (value, value))

    with open(stdin or os.devnull, "rb") as source:
        return subprocess.run(
            [sys.executable, "-m", "labcli", *args],
            cwd=cwd,
            stdout=stdout,
            stderr=subprocess.PIPE,
            text=True,
            errors=errors,
            timeout=timeout,
            env={**os.environ, "COLUMNS": "400", **(env or {})},
            stdin=source,
            preexec_fn=preexec,
        )


def at_a_terminal() -> None:
    """``preexec_fn`` of a child that is sent Ctrl-C: SIGINT at its default, as a terminal starts it.

    A child inherits an ignored SIGINT, and test runners are often started that way (a script's
    background job, some CI runners): its Ctrl-C would then be ignored, as labcli is asked to.
    """
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def finish(proc: subprocess.Popen, timeout: float = 10.0) -> tuple[str, str]:
    """The rest of a text-mode child's stdout and stderr once it exits, and its exit awaited.

    ``Popen.communicate`` reads the pipes' file descriptors, so it misses what an earlier
    ``proc.stdout.readline()`` pulled into the text wrapper's buffer: a last line that arrived in
    one read with the reply before it (seen on a loaded machine) would be lost.  The child's
    output here is a few lines, so waiting before reading cannot fill a pipe.
    """
    proc.wait(timeout=timeout)
    out = proc.stdout.read() if proc.stdout is not None else ""
    err = proc.stderr.read() if proc.stderr is not None else ""
    return out, err
