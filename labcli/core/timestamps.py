"""Wall-clock times as the toolkit writes and reads them: UTC, ISO 8601, one format.

Every time a run file, a model file or a session log records (``started``, ``ended``,
``created``, ``file_time``, ...) comes from :func:`utc_now`:
``2026-11-26T13:54:47.819444+00:00``, microseconds and the UTC offset written out, the form
``datetime.fromisoformat`` reads on every Python the toolkit supports (3.10 included).

Files written before this format was the only one also hold times to the second with a
``Z`` suffix (``2026-11-24T12:59:47Z``: a record's ``started``, a session's ``time``, every
time of a schema-1 run).  Python 3.10's ``fromisoformat`` refuses that form, and as text it
sorts after a later time of the other form (``'Z' > '.'``), so nothing compares times as
text: :func:`parse_utc` reads both forms into an aware ``datetime`` in UTC.
"""

from __future__ import annotations

import datetime as dt
import re

# What a stored time looks like: date, 'T', time to the second, an optional fraction, then
# 'Z' or a UTC offset (the one stamp format, and the 'Z' form older files hold).
_STAMP = re.compile(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d(\.\d{1,6})?(Z|[+-]\d\d:\d\d)")


def utc_now() -> str:
    """The current time, UTC, as ISO 8601 with microseconds: ``2026-11-26T13:54:47.819444+00:00``."""
    return dt.datetime.now(dt.timezone.utc).isoformat(timespec="microseconds")


def parse_utc(text: str) -> dt.datetime:
    """A stored time as an aware ``datetime`` in UTC.

    Reads :func:`utc_now`'s form and the ``...47Z`` form of older files (with or without a
    fraction of a second); ValueError, in one sentence, for anything else.
    """
    s = text.strip()
    m = _STAMP.fullmatch(s)
    if m is None:
        raise ValueError(
            f"{text!r} is not a time as labcli stores one (ISO 8601 with a UTC offset, e.g. "
            "2026-11-26T13:54:47.819444+00:00, or ending in Z)"
        )
    if m.group(2) == "Z":
        s = s[:-1] + "+00:00"
    fraction = m.group(1)
    if fraction and len(fraction) != 7:
        # 3.10's fromisoformat takes 3 or 6 digits only: pad to microseconds.
        s = s.replace(fraction, fraction.ljust(7, "0"), 1)
    return dt.datetime.fromisoformat(s).astimezone(dt.timezone.utc)
