"""One clock, one timestamp format: what the toolkit writes, and the older forms it reads.

Runs on every supported Python; on 3.10 ``datetime.fromisoformat`` refuses the ``Z`` form
that older files hold, which is what :func:`labcli.core.timestamps.parse_utc` is for.
"""

from __future__ import annotations

import datetime as dt
import re
from pathlib import Path

import h5py
import pytest
from support import toy

from labcli.core.timestamps import parse_utc, utc_now

ROOT = Path(__file__).resolve().parents[2]
UTC = dt.timezone.utc
# The one format: seconds, six digits of fraction, the UTC offset written out.
ONE_FORMAT = re.compile(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\.\d{6}\+00:00")
# Where run files keep wall-clock times (attributes and text columns alike).
TIME_NAMES = {"started", "ended", "created", "time", "file_time", "start_time"}


def stored_times(path: Path) -> dict[str, list[str]]:
    """Every wall-clock time a run file holds, by where it is, as text."""
    out: dict[str, list[str]] = {}

    def keep(where: str, value: object) -> None:
        values = value.tolist() if hasattr(value, "tolist") else value
        for v in values if isinstance(values, list) else [values]:
            s = v.decode() if isinstance(v, bytes) else str(v)
            if s:
                out.setdefault(where, []).append(s)

    with h5py.File(path, "r") as f:

        def visit(name: str, obj: object) -> None:
            for k, v in obj.attrs.items():  # type: ignore[attr-defined]
                if k in TIME_NAMES:
                    keep(f"{name}@{k}", v)
            if isinstance(obj, h5py.Dataset) and name.rsplit("/", 1)[-1] in TIME_NAMES and obj.dtype.kind == "S":
                keep(name, obj[()])

        for k, v in f.attrs.items():
            if k in TIME_NAMES:
                keep(f"/@{k}", v)
        f.visititems(visit)
    return out


def test_now_is_utc_with_microseconds_and_the_offset_written_out():
    before = dt.datetime.now(UTC)
    stamp = utc_now()
    after = dt.datetime.now(UTC)
    assert ONE_FORMAT.fullmatch(stamp), stamp
    read = dt.datetime.fromisoformat(stamp)  # the standard library's own reader, 3.10 included
    assert read.utcoffset() == dt.timedelta(0)
    assert before <= read <= after
    assert parse_utc(stamp) == read


def test_both_stored_forms_read_as_the_same_instant():
    z = parse_utc("2026-11-24T12:59:47Z")
    assert z == dt.datetime(2026, 11, 24, 12, 59, 47, tzinfo=UTC) and z.tzinfo == UTC
    assert parse_utc("2026-11-24T12:59:47+00:00") == z
    assert parse_utc("2026-11-24T12:59:47.819444+00:00") - z == dt.timedelta(microseconds=819444)
    assert parse_utc("2026-11-24T12:59:47.590156Z") - z == dt.timedelta(microseconds=590156)
    assert parse_utc("2026-11-24T12:59:47.5Z") - z == dt.timedelta(milliseconds=500)
    # Another offset is the same instant in UTC.
    assert parse_utc("2026-11-24T13:59:47+01:00") == z
    assert parse_utc("  2026-11-24T12:59:47Z\n") == z


@pytest.mark.parametrize(
    "bad",
    ["", "2026-11-24", "2026-11-24T12:59:47", "2026-11-24 12:59:47Z", "yesterday", "2026-13-24T12:59:47Z"],
)
def test_anything_else_is_one_sentence(bad):
    with pytest.raises(ValueError) as e:
        parse_utc(bad)
    if bad != "2026-13-24T12:59:47Z":  # well formed, but no such month: the standard library's words
        assert str(e.value) == (
            f"{bad!r} is not a time as labcli stores one (ISO 8601 with a UTC offset, e.g. "
            "2026-11-26T13:54:47.819444+00:00, or ending in Z)"
        )


@pytest.mark.parametrize(
    "path",
    [ROOT / "sample_runs" / f"{n}.h5" for n in ("force", "pushes", "stretch", "joint", "bent")]
    + [ROOT / "tests" / "data" / "v1" / f"{n}.h5" for n in ("force", "pushes", "stretch", "joint")],
    ids=lambda p: f"{p.parent.name}/{p.name}",
)
def test_every_time_in_existing_files_reads(path):
    times = stored_times(path)
    assert times, "no times found: the walk is wrong"
    for where, values in times.items():
        for v in values:
            assert parse_utc(v).tzinfo == UTC, (where, v)


def test_a_trial_that_began_in_the_older_form_ended_after_it_began():
    # Files written before one clock hold starts in the older form ('...47Z') beside ends in
    # today's ('...47.819444+00:00').  As text the start sorts after the end ('Z' > '.'); read, it does not.
    started, ended = "2026-11-26T13:54:47Z", "2026-11-26T13:54:47.819444+00:00"
    assert started > ended  # the text comparison is wrong
    assert parse_utc(started) < parse_utc(ended)
    assert (parse_utc(ended) - parse_utc(started)).total_seconds() == pytest.approx(0.819444)


def test_a_new_run_writes_every_time_in_the_one_format(toy_paper, tmp_path, invoke):
    run = tmp_path / "toy.h5"
    result = invoke(
        "acquire",
        run,
        "--protocol",
        toy_paper,
        "--port",
        f"sim://?mode={toy.MODE}&seed=3&clock=virtual",
        "--unattended",
    )
    assert result.exit_code == 0, result.output
    times = stored_times(run)
    # The file's own times, each record's start and end, the session log's events.
    assert {"/@file_time", "entry/start_time", "entry/trials/started", "entry/trials/ended"} <= set(times)
    assert any(w.endswith("/time") for w in times), sorted(times)
    for where, values in times.items():
        for v in values:
            assert ONE_FORMAT.fullmatch(v), (where, v)
    started = [parse_utc(s) for s in times["entry/trials/started"]]
    ended = [parse_utc(s) for s in times["entry/trials/ended"]]
    assert all(s <= e for s, e in zip(started, ended, strict=True))
