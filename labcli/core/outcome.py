"""How a session ended, in one sentence: what was stored, what was lost, how to go on.

The engine (:mod:`labcli.core.engine`) says where the session stood (:class:`Where`); the
sentences here say it to the experimenter: a finished run, a quit, an interrupt, standard
input ending at a question, a lost rig, a problem nobody is at the simulated rig to fix.
Each names the run file, what it holds, and the exact command that resumes it.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..errors import OutOfMemory


@dataclass
class Outcome:
    """How a session ended; ``message`` is the sentence to print."""

    status: str  # "finished" | "quit" | "interrupted" | "no input"
    message: str
    stored: int  # records committed by this session
    complete: int  # records complete in the file
    skipped: tuple[int, ...] = ()
    wall_s: float = 0.0

    @property
    def exit_code(self) -> int:
        return {"finished": 0, "quit": 0, "interrupted": 130, "no input": 1}[self.status]


@dataclass(frozen=True)
class Where:
    """Where a session stood when it ended."""

    noun: str  # what one record is called: "trial", "push", "point"
    run_path: str
    resume_command: str
    created: bool  # whether the run file exists
    complete: int  # records complete in it
    current: str  # "trial 3", "the pause between trials", "the setup"
    in_record: bool  # whether a record was in progress (and so lost)

    def stored(self) -> str:
        """``the 3 completed trials in run.h5 are unchanged``."""
        n = self.complete
        return (
            f"the {count(n, 'completed ' + self.noun)} in {self.run_path} {'is' if n == 1 else 'are'} unchanged"
            if self.created
            else f"nothing was written to {self.run_path}"
        )


def ended(status: str, where: Where, stored: int, skipped: tuple[int, ...], wall: float, why: str = "ended") -> Outcome:
    """The :class:`Outcome` of a session that ended as ``status`` (``stored`` records this session).

    ``why``: for "no input", what standard input did ("ended", or flooded with no line end).
    """
    n = count(where.complete, where.noun)
    if status == "finished":
        msg = f"Session complete: {n} stored in {where.run_path} ({stored} this session, {wall:.1f} s)."
        if skipped:
            msg += (
                f" Skipped {count(len(skipped), where.noun)} ({', '.join(map(str, skipped))}) "
                f"not stored; record {'it' if len(skipped) == 1 else 'them'} with: {where.resume_command}"
            )
    elif not where.created:
        msg = _before_the_file(status, where.run_path, why)
    elif status == "quit":
        msg = (
            f"Stopped at your request during {where.current}, which was not stored; "
            f"{n} stored in {where.run_path}. Resume with: {where.resume_command}"
        )
    elif status == "no input":
        lost = f", so {where.current} was not stored" if where.in_record else ""
        msg = (
            f"No input: standard input {why}{'' if why == 'ended' else ','} at a question during "
            f"{where.current}{lost}; {n} stored "
            f"in {where.run_path}. Resume where someone at the rig can answer: {where.resume_command}"
        )
    else:
        what = ", which was discarded" if where.in_record else ""
        msg = (
            f"Interrupted during {where.current}{what}; {n} stored in "
            f"{where.run_path} {'is' if where.complete == 1 else 'are'} safe. Resume with: {where.resume_command}"
        )
    return Outcome(status, msg, stored, where.complete, tuple(skipped), wall)


def _before_the_file(status: str, run_path: str, how: str = "ended") -> str:
    """A session that ended during the setup, before its run file was created."""
    why = {
        "quit": "Stopped at your request",
        "interrupted": "Interrupted",
        "no input": f"No input (standard input {how})",
    }[status]
    again = (
        "run the command where someone at the rig can answer its prompts"
        if status == "no input"
        else "run the same command again to start the run"
    )
    return f"{why} during the setup, before anything was written to {run_path}; {again}."


def rig_lost(what: str, port: str, where: Where) -> str:
    """The rig on ``port`` ``what`` ("stopped sending data") and the session cannot wait for it."""
    if not where.created:
        return (
            f"The rig on {port} {what} during the setup, before anything was written to "
            f"{where.run_path}. Check the cable and power, then run the same command again."
        )
    lost = f"that {where.noun} was not stored and " if where.in_record else ""
    return (
        f"The rig on {port} {what} during {where.current}; {lost}{where.stored()}. "
        f"Check the cable and power, then resume with: {where.resume_command}"
    )


def out_of_memory(where: Where) -> OutOfMemory:
    """Memory ran out (a MemoryError) during the session: the error saying what is safe, and how to go on."""
    if not where.created:
        return OutOfMemory(
            f"Memory ran out during the setup, before anything was written to {where.run_path}; "
            "close other programs (or raise ulimit -v) and run the same command again."
        )
    lost = ", which was not stored" if where.in_record else ""
    return OutOfMemory(
        f"Memory ran out during {where.current}{lost}; {where.stored()}. "
        f"Close other programs (or raise ulimit -v), then resume with: {where.resume_command}"
    )


def plural(noun: str) -> str:
    return noun + ("es" if noun.endswith(("sh", "ch", "s")) else "s")


def count(n: int, noun: str) -> str:
    return f"{n} {noun}" if n == 1 else f"{n} {plural(noun)}"
