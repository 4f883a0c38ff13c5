"""An acquisition protocol as a sequence of plain steps.

A *session* is a generator of step objects; it knows nothing of serial ports,
HDF5 files or terminals.  The run engine (:mod:`labcli.core.engine`) executes each
step and sends its result back into the generator, much as a bluesky plan
yields messages to its run engine::

    gen = paper.acquisition(protocol, options).session(completed=())
    reply = None
    while True:
        step = gen.send(reply)          # SetupCheck(), Prompt(...), WaitSettle(...), ...
        reply = execute(step)           # what the step returns is listed below

Because steps are plain data, a test can drive a session with made-up replies
and check every prompt and every record without a rig.  The steps are the same for
every paper; what the experimenter does at the rig is an action of the
paper's own (a frozen dataclass with ``act_on(rig)``, carried by a
:class:`Prompt`), and what a record holds is the paper's record type's business.

Replies the engine sends back:

=================  ==========================================================
step               reply
=================  ==========================================================
``SetupCheck``     ``None``
``Prompt``         ``None``, or the parsed change when the prompt offers one
                   (``change``) and the experimenter typed it instead of Enter
                   (nothing was done at the rig then); a quit ends the session
``Problem``        ``None`` once the fix was prompted (unattended: the session ends)
``Ask``            ``{field key: parsed answer}``, or ``None`` when the first
                   answer was empty and its field says that ends the questions
``BeginTrial``     ``None``
``WaitSettle``     :class:`SettleReport`, or ``"redo"``
``Baseline``       a :class:`~labcli.core.window.Window`
``Capture``        a :class:`~labcli.core.window.Window`
``Review``         ``"accept"``, ``"redo"`` or ``"skip"`` (quit ends the session)
``Commit``         ``None``
``Finish``         ``None``
``Valves``         ``{channel: state}`` as the board set its valves, or ``None``
                   when the valves are the experimenter's (a 1.0 board, a board
                   without valves, a protocol that says ``valves = "hand"``)
``Hold``           a :class:`HoldReport`: each channel's slope over the window
``Note``           ``None``
=================  ==========================================================

A captured window is one :class:`~labcli.core.window.Window` from the engine to the run
file: the engine streams it into the run file as its frames arrive and hands the session
the stored window (or, outside a trial, its statistics only), so a window of any length
takes the same memory; the session reads its length and per-channel mean and variance and
puts the window itself in the record's ``raw``.  A test may send a window held in memory
(:meth:`Window.of <labcli.core.window.Window.of>`) instead.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from .record import Record, Settle
from .window import Window

__all__ = [
    "Ask",
    "Baseline",
    "BeginTrial",
    "Capture",
    "Commit",
    "Field",
    "Finish",
    "Hold",
    "HoldReport",
    "Note",
    "Problem",
    "Prompt",
    "Review",
    "SettleReport",
    "SetupCheck",
    "Step",
    "Valves",
    "WaitSettle",
    "Window",  # what Baseline and Capture reply (labcli.core.window)
]

# --------------------------------------------------------------------------- steps


@dataclass(frozen=True)
class SetupCheck:
    """Handshake done; check channels against the protocol and live readings in range."""


@dataclass(frozen=True)
class Prompt:
    """Tell the experimenter what to do and wait for Enter.

    ``action`` (an object with ``act_on(rig)``, see :class:`labcli.core.paper.RigAction`)
    is what the prompt asks for; the simulated rig does it itself once the prompt is answered.
    ``change`` (a :class:`Field`) lets the experimenter type new values instead of Enter
    ("Enter pushes 10 mm along 0 deg, or type a new distance"); the reply is then the parsed
    value and the session prompts again with it.
    """

    text: str
    action: Any = None
    change: Field | None = None


_NO_DEFAULT: Any = object()


@dataclass(frozen=True)
class Field:
    """One question of an :class:`Ask`.

    ``prompt`` is the question, or a function of the answers given so far that words it
    (``lambda a: f"{a['name']}: radius R in mm:"``); ``parse(text)`` returns the value or raises ValueError with a sentence, after which the
    question is asked again (with ``again`` when given).  Without ``parse`` the answer is
    the text typed, stripped.  An empty answer gives ``default`` when there is one
    ("Enter keeps the default"); an empty first answer to a ``stop_if_empty`` field ends
    the questions (the reply is None).  ``simulated_only`` questions are asked only of a
    simulated rig (what a real rig would tell by itself).
    """

    key: str
    prompt: str | Callable[[dict[str, Any]], str]
    parse: Callable[[str], Any] | None = None
    default: Any = _NO_DEFAULT
    again: str | None = None
    stop_if_empty: bool = False
    simulated_only: bool = False

    @property
    def has_default(self) -> bool:
        return self.default is not _NO_DEFAULT


@dataclass(frozen=True)
class Ask:
    """Ask the experimenter for values (a load typed without a plan, an object, a push)."""

    fields: tuple[Field, ...]


@dataclass(frozen=True)
class BeginTrial:
    """A trial (or push, or point) starts: for the progress display and the engine's bookkeeping."""

    trial: int
    set: str
    index: int  # 1-based position in this session's schedule
    total: int
    label: str  # "Trial 12/108 (fit)"
    unit: str = ""  # what index and total count where the label counts something else: "captures"


@dataclass(frozen=True)
class WaitSettle:
    """Read until the rig is at equilibrium (:mod:`labcli.core.settle`)."""

    label: str  # "baseline", "load", "air supply", ...
    # Each SI channel's steady drift per second (a held chamber's leak, measured by the hold
    # check), taken out of the spreads and the tail; empty when none is known.
    drift_per_s: tuple[float, ...] = ()


@dataclass(frozen=True)
class Baseline:
    """Record the unloaded readings over ``capture_s`` seconds of device time."""

    capture_s: float


@dataclass(frozen=True)
class Capture:
    """Record the loaded readings over ``capture_s`` seconds of device time."""

    capture_s: float


@dataclass(frozen=True)
class Review:
    """Show the trial's summary row; the experimenter accepts, redoes, skips or quits.

    ``warnings`` are what the checks of the readings found (:mod:`labcli.core.guard`); with
    any, ``default`` (what Enter alone answers) is ``"redo"``, so a trial that looks wrong is
    stored only when the experimenter types ``a``.
    """

    row: dict
    warnings: tuple[str, ...] = ()
    default: str = "accept"


@dataclass(frozen=True)
class Problem:
    """The readings say the rig is not as the prompts asked (no air, a weight left on).

    Attended, the engine shows ``text`` and executes ``fix`` (a :class:`Prompt` saying what
    to do); unattended, nobody can fix it, and the session ends with ``text`` as its error.
    """

    text: str
    fix: Prompt


@dataclass(frozen=True)
class Commit:
    """Store one finished record whole (its record type is the run's; a paper types its records
    by deriving from :class:`~labcli.core.record.Record`)."""

    record: Record


@dataclass(frozen=True)
class Finish:
    """End of the schedule; ``split`` maps record ids to "fit"/"validation" (None: no split)."""

    split: dict | None
    skipped: tuple[int, ...] = ()


@dataclass(frozen=True)
class Valves:
    """Set every chamber's valve to ``state`` (``supply``, ``hold`` or ``vent``) by command, when the
    board drives them (:mod:`labcli.core.air`); the reply says whether it did.  ``channels``: only
    those chambers' valves (pressure channels' names), the others left as they are."""

    state: str
    channels: tuple[str, ...] = ()


@dataclass(frozen=True)
class Note:
    """Tell the experimenter what the session does on its own (no answer is awaited)."""

    text: str


@dataclass(frozen=True)
class Hold:
    """Watch the readings for ``duration_s`` of device time and fit each channel's slope (the hold check)."""

    duration_s: float


Step = (
    SetupCheck
    | Prompt
    | Ask
    | BeginTrial
    | WaitSettle
    | Baseline
    | Capture
    | Review
    | Problem
    | Commit
    | Finish
    | Valves
    | Hold
    | Note
)


# --------------------------------------------------------------------------- replies


@dataclass(frozen=True)
class SettleReport:
    """How a window's equilibrium was reached (the reply of :class:`WaitSettle`)."""

    settled: bool  # False: timed out and accepted by the experimenter
    settle_time_s: float  # device time from the start of the wait to equilibrium
    waited_s: float  # device time spent waiting in all
    pressure_spread_MPa: float
    angle_spread_rad: float
    criterion: str

    def as_dict(self) -> Settle:
        """What a record's ``settle`` keeps of it."""
        return {
            "settled": self.settled,
            "settle_time_s": self.settle_time_s,
            "waited_s": self.waited_s,
            "pressure_spread_MPa": self.pressure_spread_MPa,
            "angle_spread_rad": self.angle_spread_rad,
            "criterion": self.criterion,
        }


@dataclass(frozen=True)
class HoldReport:
    """What the readings did over a :class:`Hold`: per channel (SI), the least-squares slope per
    second and the mean, over ``frames`` frames spanning ``duration_s`` of device time."""

    slope_per_s: Any  # numpy (k,)
    mean: Any  # numpy (k,)
    frames: int
    duration_s: float
