"""A KeyboardInterrupt raised in a finaliser is kept for the next safe point, not printed and lost."""

from __future__ import annotations

import subprocess
import sys

import pytest

from labcli.core import interrupts


class _Doomed:
    def __init__(self, exc: type[BaseException]) -> None:
        self.exc = exc

    def __del__(self):
        raise self.exc


def _drop(exc: type[BaseException]) -> None:
    doomed = _Doomed(exc)
    del doomed


def test_kept_inside_raised_once_at_the_check(capsys):
    with interrupts.kept():
        _drop(KeyboardInterrupt)
        assert interrupts.pending()
        with pytest.raises(KeyboardInterrupt):
            interrupts.check()
        interrupts.check()  # raised once only
    assert capsys.readouterr().err == ""


@pytest.fixture
def heard(monkeypatch):
    """The hook in place before (Python's own, or pytest's): what reached it."""
    seen: list[type[BaseException]] = []
    monkeypatch.setattr(sys, "unraisablehook", lambda u: seen.append(u.exc_type))
    return seen


def test_other_errors_in_finalisers_still_reach_the_previous_hook(heard):
    with interrupts.kept():
        _drop(ValueError)
        assert not interrupts.pending()
    assert heard == [ValueError]


def test_outside_the_hook_python_behaves_as_before(heard):
    before = sys.unraisablehook
    with interrupts.kept():
        pass
    assert sys.unraisablehook is before
    _drop(KeyboardInterrupt)
    assert not interrupts.pending()
    assert heard == [KeyboardInterrupt]


def test_a_stale_interrupt_is_not_carried_into_the_next_session():
    with interrupts.kept():
        _drop(KeyboardInterrupt)
    with interrupts.kept():
        interrupts.check()  # nothing raised: the earlier one belonged to the earlier session


def test_a_real_sigint_in_a_finaliser_is_kept():
    # The signal itself, not a raise: SIGINT is delivered while a __del__ runs Python code.
    code = """
import os, signal, time
from labcli.core import interrupts

signal.signal(signal.SIGINT, signal.default_int_handler)  # a test runner's worker may pass SIGINT on ignored

class Slow:
    def __del__(self):
        os.kill(os.getpid(), signal.SIGINT)
        t = time.monotonic()
        while time.monotonic() - t < 30:  # Python code: the handler runs here, inside the finaliser,
            pass                             # and ends the loop (30 s only if it never comes)

with interrupts.kept():
    s = Slow()
    del s
    try:
        interrupts.check()
    except KeyboardInterrupt:
        print("kept")
"""
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert (r.returncode, r.stdout.strip(), r.stderr) == (0, "kept", "")
