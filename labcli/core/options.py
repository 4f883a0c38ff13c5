"""Options declared as data: what a paper's analyses and simulated rigs may be asked.

In the spirit of pymeasure's Parameters, a paper does not parse its options; it declares
them, and the core builds the command line (``labcli fit --form paper``), the ``sim://``
URL (``sim://?mode=mckibben&leak=2``) and the refusals from the declaration.  A paper
declares the options of one analysis, or of its simulated rigs, as a frozen dataclass whose
fields are made by the helpers below (:func:`number`, :func:`choice`, :func:`switch`, ...)::

    @dataclass(frozen=True)
    class FitOptions:
        form: str = choice(("posture", "paper"), "posture", help="...")
        max_amplification: float | None = number(help="...", minimum=1, above=True)

The dataclass is the typed options object the analysis receives (``options.form``);
:func:`declared` reads its declaration back (one :class:`Option` per field) and
:func:`build` makes one from the values a person gave, refusing names it does not declare.
The default of a field is its value when the option is not given; ``None`` means "not
given" (the analysis, or the rig, then uses its own default, which ``default_text`` names).

Nothing here knows click: :mod:`labcli.commands._declared` turns a declaration into click
options and :mod:`labcli.core.sim.url` into ``sim://`` options.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeVar

from ..errors import ConfigError

_KEY = "labcli.option"
KINDS = ("number", "integer", "switch", "choice", "path", "text")

T = TypeVar("T")


class BadValue(ValueError):
    """A value an option refuses, in its own words (the sentence shown as it is).

    A plain :class:`ValueError` from a parser is shown as "must be <what>" instead.
    """


@dataclass(frozen=True)
class Option:
    """One declared option.

    ``kind``: ``number`` (a finite float), ``integer``, ``switch`` (on or off: ``--name`` on
    the command line, ``name=0|1`` in a URL), ``choice`` (one of ``choices``), ``path`` (a
    file path) or ``text``; ``parse(text) -> value`` replaces the kind's own reading
    (ValueError when malformed; :class:`BadValue` with its own sentence).  ``minimum`` and
    ``maximum`` bound a number (``above``: the minimum itself excluded).  ``units`` are the
    units a person types ("kPa", "MPa", "" for none); ``what`` says what a valid value is
    ("a number >= 0"; derived from the kind when empty), ``form`` how a value shows in
    usage lines (``X``, ``0|1``, ``KEY=VALUE``).  ``repeat``: the option may be given
    several times (a tuple of values).  ``required``: the analysis cannot run without it.
    ``default_text`` names what a ``None`` default stands for ("the protocol's, 96 kPa").
    ``flag`` is the command-line spelling (default ``--`` and the name with dashes).
    ``name`` is the dataclass field's, filled in by :func:`declared`.
    """

    kind: str = "text"
    default: Any = None
    help: str = ""
    units: str = ""
    choices: tuple[str, ...] = ()
    minimum: float | None = None
    maximum: float | None = None
    above: bool = False
    parse: Callable[[str], Any] | None = None
    what: str = ""
    form: str = ""
    repeat: bool = False
    required: bool = False
    default_text: str = ""
    flag: str = ""
    name: str = ""

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"option kind must be one of {', '.join(KINDS)}, not {self.kind!r}")
        if self.kind == "choice" and not self.choices:
            raise ValueError("a choice option needs its choices")

    @property
    def cli_flag(self) -> str:
        """How the option is typed on the command line: ``--max-amplification``."""
        return self.flag or "--" + self.name.replace("_", "-")

    @property
    def accepted(self) -> str:
        """What a valid value is, in words (for refusals)."""
        if self.what:
            return self.what
        if self.kind == "switch":
            return "0 or 1"
        if self.kind == "choice":
            return "one of " + ", ".join(self.choices)
        if self.kind == "path":
            return "the path of a file"
        if self.kind in ("number", "integer"):
            return _range_words("a whole number" if self.kind == "integer" else "a number", self)
        return "a text"

    @property
    def metavar(self) -> str:
        """How a value shows in usage lines and accepted forms (``X``, ``0|1``, ``paper|thin``)."""
        if self.form:
            return self.form
        return {
            "switch": "0|1",
            "choice": "|".join(self.choices),
            "path": "PATH",
            "integer": "N",
            "number": "X",
        }.get(self.kind, "TEXT")

    def read(self, text: str) -> Any:
        """The value of ``text`` as typed (in a URL, or by a custom parser): ValueError when malformed."""
        if self.parse is not None:
            return self.parse(text)
        if self.kind == "switch":
            if text not in ("0", "1"):
                raise ValueError(text)
            return text == "1"
        if self.kind == "choice":
            if text not in self.choices:
                raise ValueError(text)
            return text
        if self.kind == "path":
            if not text:
                raise ValueError(text)
            return Path(text)
        if self.kind in ("number", "integer"):
            return self.within(int(text) if self.kind == "integer" else float(text))
        return text

    def within(self, value: float) -> Any:
        """``value`` if it is finite and inside the bounds; ValueError otherwise."""
        if not math.isfinite(value):
            raise ValueError(value)
        lo, hi = self.minimum, self.maximum
        if lo is not None and (value <= lo if self.above else value < lo):
            raise ValueError(value)
        if hi is not None and value > hi:
            raise ValueError(value)
        return value

    def help_text(self) -> str:
        """The help line: what it does, its units and its default."""
        notes = [f"units: {self.units}"] if self.units else []
        if self.required:
            notes.append("required")
        elif self.default_text:
            notes.append(f"default: {self.default_text}")
        elif self.default not in (None, False, ()):
            notes.append(f"default: {self.default}")
        return self.help + (f"  [{'; '.join(notes)}]" if notes else "")


def _range_words(noun: str, opt: Option) -> str:
    lo, hi = opt.minimum, opt.maximum
    if lo is not None and hi is not None:
        return f"{noun} within {lo:g}..{hi:g}" + (f" above {lo:g}" if opt.above else "")
    if lo is not None:
        return f"{noun} {'>' if opt.above else '>='} {lo:g}"
    if hi is not None:
        return f"{noun} <= {hi:g}"
    return noun


# --------------------------------------------------------------------------- declaring


def option(decl: Option) -> Any:
    """A dataclass field declaring ``decl`` (its default the field's)."""
    default = tuple(decl.default or ()) if decl.repeat else decl.default
    return field(default=default, metadata={_KEY: decl})


def number(
    default: float | None = None,
    *,
    help: str,
    units: str = "",
    minimum: float | None = None,
    maximum: float | None = None,
    above: bool = False,
    default_text: str = "",
    parse: Callable[[str], Any] | None = None,
    form: str = "",
) -> Any:
    """A number option (a finite float, within the bounds given)."""
    return option(
        Option(
            "number",
            default,
            help,
            units,
            minimum=minimum,
            maximum=maximum,
            above=above,
            parse=parse,
            form=form,
            default_text=default_text,
        )
    )


def integer(
    default: int | None = None,
    *,
    help: str,
    minimum: int | None = None,
    maximum: int | None = None,
    default_text: str = "",
    parse: Callable[[str], Any] | None = None,
) -> Any:
    """A whole-number option."""
    return option(
        Option("integer", default, help, minimum=minimum, maximum=maximum, parse=parse, default_text=default_text)
    )


def switch(*, help: str) -> Any:
    """An option that is on or off (off unless given)."""
    return option(Option("switch", False, help))


def choice(choices: tuple[str, ...], default: str | None = None, *, help: str, default_text: str = "") -> Any:
    """One of ``choices``."""
    return option(Option("choice", default, help, choices=tuple(choices), default_text=default_text))


def path(*, help: str, required: bool = False, default_text: str = "") -> Any:
    """A file path (``pathlib.Path``), None when not given."""
    return option(Option("path", None, help, required=required, default_text=default_text))


def text(
    default: Any = None,
    *,
    help: str,
    parse: Callable[[str], Any] | None = None,
    what: str = "",
    form: str = "",
    units: str = "",
    repeat: bool = False,
    default_text: str = "",
    flag: str = "",
) -> Any:
    """A text option, or a value of its own form read by ``parse`` (``what`` says what it takes)."""
    return option(
        Option(
            "text",
            default,
            help,
            units,
            parse=parse,
            what=what,
            form=form,
            repeat=repeat,
            default_text=default_text,
            flag=flag,
        )
    )


# --------------------------------------------------------------------------- reading back


def declared(cls: type) -> tuple[Option, ...]:
    """The options a declaration (a dataclass of :func:`option` fields) holds, in field order."""
    if not dataclasses.is_dataclass(cls):
        raise TypeError(f"{cls!r} is not a dataclass of declared options")
    out = []
    for f in dataclasses.fields(cls):
        decl = f.metadata.get(_KEY)
        if not isinstance(decl, Option):
            raise TypeError(f"{cls.__name__}.{f.name} is not a declared option (make it with labcli.core.options)")
        out.append(dataclasses.replace(decl, name=f.name))
    return tuple(out)


def names(cls: type | None) -> tuple[str, ...]:
    """The option names of a declaration (none for None)."""
    return () if cls is None else tuple(o.name for o in declared(cls))


def build(cls: type[T], values: Mapping[str, Any]) -> T:
    """The options object of declaration ``cls`` with ``values`` given (name -> value); the rest default.

    ValueError naming the first name ``cls`` does not declare.
    """
    known = set(names(cls))
    unknown = [n for n in values if n not in known]
    if unknown:
        raise ValueError(f"{cls.__name__} declares no option {unknown[0]!r}")
    return cls(**dict(values))


def given(options: Any, decls: Iterable[Option]) -> dict[str, Any]:
    """The values of ``options`` that differ from their declared defaults (what was asked for)."""
    return {o.name: getattr(options, o.name) for o in decls if getattr(options, o.name) != o.default}


# --------------------------------------------------------------------------- what a person typed


@dataclass(frozen=True)
class Typed:
    """The declared options a person gave a command: name -> value, in the order typed, and
    how each was spelled (``--set``), for the sentences that refuse them."""

    values: Mapping[str, Any] = field(default_factory=dict)
    flags: Mapping[str, str] = field(default_factory=dict)

    def flag(self, name: str) -> str:
        return self.flags.get(name) or "--" + name.replace("_", "-")


class OptionRefused(ConfigError):
    """An option given to a paper (or a rig) that does not declare it; the text is the sentence."""


def bind(cls: type[T] | None, typed: Typed, *, owners: Callable[[str], list[str]], subject: str) -> T | None:
    """The options object of ``cls`` from what was typed.

    An option ``cls`` does not declare is refused in one sentence: "--set is an option of
    rpam2015 runs; out/force.h5 is a run of kind force (takuma2014)."  ``owners(name)`` names who
    declares it ("rpam2015 runs"); ``subject`` says what the input is.  A required option
    left out is refused too.  ``cls`` None (nothing declared) takes no option at all.
    """
    known = {o.name: o for o in declared(cls)} if cls is not None else {}
    for name in typed.values:
        if name not in known:
            holders = owners(name)
            who = " and ".join(holders) if holders else "another paper"
            raise OptionRefused(f"{typed.flag(name)} is an option of {who}; {subject}.")
    for o in known.values():
        if o.required and o.name not in typed.values:
            raise OptionRefused(f"Missing option '{o.cli_flag}'; {subject}.")
    if cls is None:
        return None
    return build(cls, typed.values)
