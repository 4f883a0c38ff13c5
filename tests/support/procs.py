"""Reading what a child process wrote, once it has ended."""

from __future__ import annotations

import subprocess


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
