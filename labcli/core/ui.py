"""What the experimenter sees and types during ``labcli acquire``.

Two implementations of one small interface:

* :class:`RichUI` prints prompts, a progress line per trial, a settling status
  and the summary table with ``rich``, and reads answers line by line from
  standard input (a terminal, a pipe or a test runner alike);
* :class:`UnattendedUI` answers every prompt itself, for the simulated rig,
  and prints one line per trial once the trial is stored.

Typing ``q`` at any prompt raises :class:`QuitRequested`; the engine then
discards the trial in progress and says how to resume.  Input that ends (a closed
or exhausted standard input) raises :class:`InputEnded`, which the engine reports as
such: nobody is there to answer.

While the engine waits for equilibrium, q and r pressed on a terminal act at once (quit,
redo the trial), read as single keys without Enter (:func:`settle_keys`).

Keys typed ahead are discarded before every question on a terminal: an Enter pressed
twice at "hang 500 g" must not also answer "remove the weight".  Each answer then comes
from a key pressed after its question was shown, whose echo ends the question's line,
so the settling status that follows never overwrites a question.
"""

from __future__ import annotations

import contextlib
import math
import os
import sys
from collections.abc import Callable, Iterator
from typing import IO, Any

from .steps import Ask, BeginTrial, Prompt


class QuitRequested(Exception):
    """The experimenter typed q."""


class InputEnded(QuitRequested):
    """Standard input ended (or was closed) at a question: nobody is there to answer."""

    why = "ended"  # how the outcome says it: "standard input {why} at a question"


MAX_ANSWER_CHARS = 4096  # an answer is a typed line; a stream of bytes with no line end is no one typing


class InputFlood(InputEnded):
    """Standard input sent more than :data:`MAX_ANSWER_CHARS` with no line end (``</dev/zero``)."""

    why = f"sent more than {MAX_ANSWER_CHARS} characters with no line end, as a device such as /dev/zero does"


def _bounded_line(stream: Any) -> str:
    """One line of at most ``MAX_ANSWER_CHARS + 1`` characters (a stream that takes no size: its line)."""
    try:
        return stream.readline(MAX_ANSWER_CHARS + 1)
    except TypeError:  # an embedding program's stream object with a plain readline()
        return stream.readline()


def _is_tty(stream: Any) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, OSError, ValueError):
        return False


def discard_typeahead(stream: Any) -> None:
    """Drop what was typed on a terminal but not yet read (harmless on anything else)."""
    try:
        if stream is None or not stream.isatty():
            return
        import termios

        termios.tcflush(stream.fileno(), termios.TCIFLUSH)
    except (ImportError, AttributeError, ValueError, OSError):
        pass  # not a terminal after all, or no termios (Windows): nothing typed ahead to drop


SETTLE_KEYS = "  (q quits, r redoes)"
REVIEW_TEXT = "Accept [a], redo [r], skip [s], note [n] or quit [q]?"
_SETTLE_KEYS = {"q": "quit", "r": "redo"}


@contextlib.contextmanager
def settle_keys(stream: Any) -> Iterator[Callable[[], str | None]]:
    """``key()``: ``"quit"`` or ``"redo"`` once q or r was pressed on the terminal ``stream``, else None.

    Only a terminal is read: keys come one at a time (cbreak mode, for the duration of the
    block) and are read only when there; an answer piped in for a later question is never
    taken.  Other keys pressed meanwhile are dropped, as typed-ahead keys are at a question.
    """
    fd = -1
    try:
        if stream is not None and stream.isatty():
            fd = stream.fileno()
    except (AttributeError, ValueError, OSError):
        fd = -1
    try:
        import select
        import termios
        import tty
    except ImportError:  # no termios (Windows): the wait reads no keys
        fd = -1
    if fd < 0:
        yield lambda: None
        return
    saved = termios.tcgetattr(fd)
    tty.setcbreak(fd, termios.TCSANOW)

    def key() -> str | None:
        try:
            while select.select([fd], [], [], 0)[0]:
                typed = os.read(fd, 64).decode(errors="replace").lower()
                if not typed:
                    return None
                for ch in typed:
                    if ch in _SETTLE_KEYS:
                        return _SETTLE_KEYS[ch]
        except OSError:
            return None
        return None

    try:
        yield key
    finally:
        with contextlib.suppress(termios.error, OSError):
            termios.tcsetattr(fd, termios.TCSANOW, saved)


def fmt_duration(seconds: float) -> str:
    s = int(round(seconds))
    if s < 60:
        return f"{s} s"
    if s < 3600:
        return f"{s // 60} min {s % 60:02d} s"
    return f"{s // 3600} h {(s % 3600) // 60:02d} min"


def progress_text(step: BeginTrial, stored: int, elapsed_s: float, remaining_s: float | None) -> str:
    """Trial n of N, set, elapsed and remaining estimate in one line."""
    done = step.index - 1
    width = 24
    filled = int(round(width * done / step.total)) if step.total else 0
    bar = "#" * filled + "-" * (width - filled)
    left = "estimating" if remaining_s is None else f"about {fmt_duration(remaining_s)} left"
    return (
        f"{step.label}  [{bar}] {done}/{step.total} {step.unit + ' ' if step.unit else ''}done "
        f"({stored} stored this session)  "
        f"elapsed {fmt_duration(elapsed_s)}, {left}"
    )


def spreads_text(status: Any, criteria: Any) -> str:
    ps = status.pressure_spread_MPa
    an = status.angle_spread_rad
    p = "-" if math.isnan(ps) else f"{ps * 1e3:.2f}"
    a = "-" if math.isnan(an) else f"{math.degrees(an):.3f}"
    return (
        f"pressure spread {p} kPa (limit {criteria.pressure_spread_MPa * 1e3:g} kPa), "
        f"angle spread {a} deg (limit {math.degrees(criteria.angle_spread_rad):.3g} deg), "
        f"quiet for {status.quiet_s:.1f} s of {criteria.hold_s:g} s"
    )


def settle_text(label: str, status: Any, criteria: Any) -> str:
    return f"settling ({label}): {status.elapsed_s:.1f} s, {spreads_text(status, criteria)}"


class RichUI:
    """Prompts on a terminal (or any line-oriented stdin)."""

    unattended = False

    def __init__(self, console: Any = None, stdin: IO[str] | None = None) -> None:
        from rich.console import Console

        self.console = console or Console(highlight=False)
        self._stdin = stdin
        self.pending_note = ""  # typed at a review (n), taken by the engine with the record

    @property
    def _interactive(self) -> bool:
        stream = self._stdin or sys.stdin
        try:
            return bool(stream.isatty())
        except (AttributeError, ValueError):
            return False

    # -- output
    def info(self, text: str) -> None:
        self.console.print(text, markup=False)

    def warn(self, text: str) -> None:
        self.console.print(f"[bold yellow]Warning:[/] {_esc(text)}")

    def begin_trial(self, step: BeginTrial, stored: int, elapsed_s: float, remaining_s: float | None) -> None:
        self.console.rule(style="dim")
        self.console.print(_esc(progress_text(step, stored, elapsed_s, remaining_s)), style="bold")

    @contextlib.contextmanager
    def settling(self, label: str, criteria: Any) -> Iterator[Any]:
        """A live status line while the engine waits for equilibrium.

        Yields ``show(status)``, which returns a key the experimenter pressed meanwhile on a
        terminal: ``"quit"`` (q) or ``"redo"`` (r), else None.  The terminal reads single keys
        for the wait (no Enter, no echo) and is put back as it was after it.
        """
        with settle_keys(self._stdin if self._stdin is not None else sys.stdin) as key:
            if self.console.is_terminal:
                with self.console.status(f"settling ({label})") as status:

                    def show(s: Any) -> str | None:
                        status.update(_esc(settle_text(label, s, criteria) + SETTLE_KEYS))
                        return key()

                    yield show
            else:
                yield lambda s: key()

    def settled(self, label: str, report: Any) -> None:
        what = "settled" if report.settled else "accepted without settling"
        self.console.print(
            f"  {label}: {what} after {report.settle_time_s:.2f} s "
            f"(pressure spread {report.pressure_spread_MPa * 1e3:.2f} kPa, "
            f"angle spread {math.degrees(report.angle_spread_rad):.3f} deg)",
            markup=False,
        )

    # -- input
    def _ask(self, text: str) -> str:
        stream = self._stdin if self._stdin is not None else sys.stdin
        if stream is None or getattr(stream, "closed", False):
            raise InputEnded("standard input is closed")
        discard_typeahead(stream)
        self.console.print(_esc(text) + " ", end="", soft_wrap=True)
        try:
            typed = self._stdin is None and _is_tty(stream)  # input(): line editing on a terminal
            line = input() if typed else _bounded_line(stream)
        except MemoryError:
            self.console.print()
            raise InputFlood("standard input floods") from None
        except (EOFError, RuntimeError, OSError, ValueError):
            # EOF, a lost sys.stdin (RuntimeError), a terminal that went away (OSError, EIO)
            self.console.print()
            raise InputEnded("standard input ended") from None
        if not typed and line == "":  # readline's end of input (input() raised EOFError instead)
            self.console.print()
            raise InputEnded("standard input ended")
        if len(line) > MAX_ANSWER_CHARS:
            self.console.print()
            raise InputFlood("standard input floods")
        line = line.rstrip("\r\n")
        if not self._interactive:
            # Answers from a pipe or a script are not echoed by a terminal: echo them,
            # so the transcript reads as the session went.
            self.console.print(line, markup=False, highlight=False)
        if line.strip().lower() in ("q", "quit"):
            raise QuitRequested("quit")
        return line

    def prompt(self, step: Prompt) -> Any:
        """Wait for Enter; with ``step.change``, typed values instead are parsed and returned."""
        answer = self._ask(f"{step.text} (q to quit):")
        change = step.change
        while change is not None and answer.strip():
            try:
                return _answer(change, answer)
            except ValueError as e:
                self.console.print(f"[red]{_esc(str(e))}[/]")
                answer = self._ask(change.again or f"{step.text} (q to quit):")
        return None

    def ask(self, step: Ask, simulated: bool = False) -> dict[str, Any] | None:
        """Ask each field in turn until its answer parses; None when a stopping field is left empty."""
        answers: dict[str, Any] = {}
        for field in step.fields:
            if field.simulated_only and not simulated:
                continue
            text = field.prompt(answers) if callable(field.prompt) else field.prompt
            answer = self._ask(text)
            if field.stop_if_empty and not answer.strip():
                return None
            while True:
                try:
                    answers[field.key] = _answer(field, answer)
                    break
                except ValueError as e:
                    self.console.print(f"[red]{_esc(str(e))}[/]")
                    answer = self._ask(field.again or text)
        return answers

    def settle_timeout(self, label: str, status: Any, criteria: Any) -> str:
        self.console.print(
            f"[yellow]Not settled ({label}) after {status.elapsed_s:.1f} s:[/] " + _esc(spreads_text(status, criteria))
        )
        return self._choose("Accept these readings [a], wait longer [w] or redo the trial [r]?", "awr", "w")

    def review(self, row: dict, warnings: tuple[str, ...] = (), default: str = "accept") -> str:
        from rich import box
        from rich.table import Table

        needed = sum(max(len(k), len(v)) + 3 for k, v in row.items())
        if needed <= self.console.width:
            table = Table(box=box.SIMPLE_HEAD, header_style="bold")
            for key in row:
                table.add_column(_esc(key), no_wrap=True)
            table.add_row(*(_esc(v) for v in row.values()))
        else:  # a narrow terminal: one line per column
            table = Table(box=box.SIMPLE, show_header=False)
            table.add_column(no_wrap=True, style="bold")
            table.add_column(no_wrap=True)
            for key, value in row.items():
                table.add_row(_esc(key), _esc(value))
        self.console.print(table)
        for w in warnings:
            self.warn(w)
        what = next(iter(row), "record")  # "trial", "push", "point": the row's id column
        while True:
            choice = self._choose(REVIEW_TEXT, "arsnq", default[0])
            if choice != "note":
                return choice
            text = self._ask(f"Note on this {what} (one line; Enter for none):").strip()
            if text:
                self.pending_note = text
                self.console.print(f"  The note is stored with the {what} once it is accepted.", markup=False)

    def take_note(self) -> str:
        """The note typed at the last review (``n``), once; "" when none."""
        note, self.pending_note = self.pending_note, ""
        return note

    def _choose(self, text: str, keys: str, default: str) -> str:
        words = {"a": "accept", "r": "redo", "s": "skip", "w": "wait", "q": "quit", "n": "note"}
        while True:
            answer = self._ask(f"{text} ({default}):").strip().lower() or default
            if answer[:1] in keys and (len(answer) == 1 or answer == words[answer[0]]):
                return words[answer[0]]
            self.console.print(f"[red]Type one of {', '.join(keys)}.[/]")


class UnattendedUI:
    """Answers every prompt itself (simulated rig only) and prints one line per trial, once it is stored."""

    unattended = True

    def __init__(self, console: Any = None, verbose: bool = False) -> None:
        from rich.console import Console

        self.console = console or Console(highlight=False)
        self.verbose = verbose
        self._step: BeginTrial | None = None
        self._accepted: tuple[dict, tuple[str, ...]] | None = None  # reviewed, not yet stored

    def info(self, text: str) -> None:
        self.console.print(text, markup=False)

    def warn(self, text: str) -> None:
        self.console.print(f"Warning: {text}", markup=False)

    def begin_trial(self, step: BeginTrial, stored: int, elapsed_s: float, remaining_s: float | None) -> None:
        self._step = step
        if self.verbose:
            self.console.print(progress_text(step, stored, elapsed_s, remaining_s), markup=False)

    @contextlib.contextmanager
    def settling(self, label: str, criteria: Any) -> Iterator[Any]:
        yield lambda s: None

    def settled(self, label: str, report: Any) -> None:
        if not report.settled:
            self.warn(f"{label}: not settled after {report.waited_s:.1f} s, readings accepted")

    def prompt(self, step: Prompt) -> Any:
        if self.verbose:
            self.console.print(f"  {step.text} [done by the simulated rig]", markup=False)
        return None

    def ask(self, step: Ask, simulated: bool = False) -> dict[str, Any] | None:
        raise QuitRequested("unattended mode cannot answer questions: it needs a plan")

    def settle_timeout(self, label: str, status: Any, criteria: Any) -> str:
        return "accept"

    def review(self, row: dict, warnings: tuple[str, ...] = (), default: str = "accept") -> str:
        """Accepts every trial; its line is printed once it is stored (:meth:`stored`)."""
        self._accepted = (row, warnings)
        return "accept"

    def stored(self) -> None:
        """The trial last reviewed is committed: its line, and what the checks found (it stays with
        the record).  Not before: nobody reads a line on the screen as a trial that a kill may yet lose."""
        if self._accepted is None:
            return
        row, warnings = self._accepted
        self._accepted = None
        self.console.print("  " + "  ".join(f"{k} {v}" for k, v in row.items()), markup=False)
        for w in warnings:
            self.warn(w)


class ProgressUI(UnattendedUI):
    """Acts out every prompt like :class:`UnattendedUI` but prints nothing (a quiet console): it
    reports ``progress(stage, stored, total)`` at each trial instead (for ``labcli demo``)."""

    def __init__(self, stage: str, progress: Callable[[str, int, int], None] | None = None) -> None:
        from rich.console import Console

        super().__init__(console=Console(quiet=True))
        self.stage = stage
        self.progress = progress

    def begin_trial(self, step: BeginTrial, stored: int, elapsed_s: float, remaining_s: float | None) -> None:
        super().begin_trial(step, stored, elapsed_s, remaining_s)
        if self.progress is not None:
            self.progress(self.stage, stored, int(step.total))


def _answer(field: Any, text: str) -> Any:
    """The value of one typed answer (ValueError with a sentence when it does not parse)."""
    if not text.strip() and field.has_default:
        return field.default
    return field.parse(text) if field.parse is not None else text.strip()


def _esc(text: str) -> str:
    from rich.markup import escape

    return escape(text)
