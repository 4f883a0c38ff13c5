"""Numbers of things in sentences: "1 completed trial", "2 completed trials", "1 push", "3 pushes"."""

from __future__ import annotations


def plural(noun: str) -> str:
    """The plural of a phrase's last word ("completed trial" -> "completed trials", "push" -> "pushes")."""
    return noun + ("es" if noun.endswith(("sh", "ch", "s", "x")) else "s")


def count(n: int, noun: str, many: str | None = None) -> str:
    """``n`` and the phrase, singular for exactly one (``many``: an irregular plural)."""
    return f"{n} {noun}" if n == 1 else f"{n} {many or plural(noun)}"
