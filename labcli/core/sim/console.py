"""The operator's console of a simulated rig: one typed line per action.

``labcli sim --pty`` reads these lines on its own standard input, so a person
can act out a protocol with two terminals and no Python: one serves the rig
and takes the operator's actions, the other runs ``labcli monitor`` or
``labcli acquire`` on the printed port.

The actions are the rig's own: a rig offers them as ``console_commands``, a
mapping of command name to :class:`ConsoleCommand` (the McKibben rig's are in
:mod:`labcli.papers.takuma2014.sim.console`: ``supply``, ``hang``, ``push``,
``state``, ...).  Every rig's console also knows:

=====================  =================================================
``wait SECONDS``       let the rig's clock run (idle port only)
``help``               the list of commands
``quit``               stop serving
=====================  =================================================

Each line gets one reply line: ``ok ...`` with what was done and the rig's
time, a command's own report (``state ...``), or ``error: ...`` for a bad
line (the rig is left as it was).
"""

from __future__ import annotations

import math
import os
import select
import shlex
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, TextIO


class ConsoleError(ValueError):
    """A line the console cannot act on; its text is the reply."""


@dataclass(frozen=True)
class ConsoleCommand:
    """One operator action: ``act(rig, args) -> reply``; ``usage`` as ``help`` and errors show it."""

    usage: str
    act: Callable[[Any, list[str]], str]


MAX_WAIT_S = 3600.0  # one wait: an hour of the rig's clock (time.sleep refuses 1e20 s; nobody means it)


def numbers(args: list[str], names: tuple[str, ...], usage: str) -> list[float]:
    """``args`` as finite numbers named ``names`` (ConsoleError with the usage otherwise)."""
    if len(args) != len(names):
        raise ConsoleError(f"usage: {usage}")
    out = []
    for name, a in zip(names, args, strict=False):
        try:
            v = float(a)
        except ValueError:
            raise ConsoleError(f"{name} must be a number, got '{a}'; usage: {usage}") from None
        if not math.isfinite(v):
            raise ConsoleError(f"{name} must be finite, got '{a}'; usage: {usage}")
        out.append(v)
    return out


def commands_of(rig: Any) -> Mapping[str, ConsoleCommand]:
    """The rig's own console commands (none for a rig that offers no ``console_commands``)."""
    return getattr(rig, "console_commands", None) or {}


def help_text(rig: Any) -> str:
    usages = [c.usage for c in commands_of(rig).values()] + ["wait SECONDS", "help", "quit"]
    return "commands: " + ", ".join(usages)


def execute(rig: Any, line: str, *, idle_wait: Callable[[float], object] | None = None) -> str:
    """Act on one console line and return the reply (``error: ...`` for a bad line).

    ``idle_wait(seconds)`` lets the clock run for ``wait`` (None: advance the rig's clock).
    """
    try:
        words = shlex.split(line)
    except ValueError as e:
        return f"error: {e}"
    if not words:
        return ""
    cmd, args = words[0].lower(), words[1:]
    try:
        return _act(rig, cmd, args, idle_wait)
    except ValueError as e:  # ConsoleError, or the rig's own refusals (out of range, beyond its reach)
        return f"error: {e}"


def _act(rig: Any, cmd: str, args: list[str], idle_wait: Callable[[float], object] | None) -> str:
    own = commands_of(rig)
    if cmd in own:
        return own[cmd].act(rig, args)
    if cmd == "help":
        numbers(args, (), "help")
        return help_text(rig)
    if cmd == "wait":
        (seconds,) = numbers(args, ("seconds",), "wait SECONDS")
        if seconds < 0:
            raise ConsoleError(f"seconds must be >= 0, got {seconds:g}")
        if seconds > MAX_WAIT_S:
            raise ConsoleError(
                f"seconds must be at most {MAX_WAIT_S:g} (an hour), got {seconds:g}; wait again for longer"
            )
        (idle_wait or rig.advance)(seconds)
        return f"ok wait {seconds:g} s (t={rig.time_s:.3f} s)"
    if cmd == "quit":
        numbers(args, (), "quit")
        return "ok quit"
    raise ConsoleError(f"unknown command '{cmd}'; {help_text(rig)}")


class StdinConsole:
    """The operator's lines from a text stream (``labcli sim``'s standard input), one action each.

    ``operate(line) -> reply`` acts on a line (a pty server's ``operate``), ``echo(reply)``
    shows the reply.  :meth:`poll` waits for input without blocking the caller longer than
    its timeout; at the end of the input ``open`` turns False (the rig goes on serving).
    """

    def __init__(self, stream: TextIO, operate: Callable[[str], str], echo: Callable[[str], None]) -> None:
        self.operate, self.echo = operate, echo
        self._buf = b""
        try:
            self._fd = stream.fileno()
            self.open = True
        except (AttributeError, OSError, ValueError):
            self._fd, self.open = -1, False

    def poll(self, timeout: float) -> None:
        """Wait up to ``timeout`` seconds for typed lines and act on each complete one."""
        try:
            ready, _, _ = select.select([self._fd], [], [], timeout)
        except (OSError, ValueError):
            self.open = False
            return
        if not ready:
            return
        data = os.read(self._fd, 4096)
        if not data:  # end of input: keep serving, stop listening
            self.open = False
            return
        self._buf += data
        *lines, self._buf = self._buf.split(b"\n")
        for raw in lines:
            reply = self.operate(raw.decode("utf-8", "replace").strip())
            if reply:
                self.echo(reply)
