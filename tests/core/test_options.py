"""Options declared as data (:mod:`labcli.core.options`), as the command line and ``sim://`` read them.

A declaration is a frozen dataclass of option fields; the same declaration gives the typed
object an analysis receives, the click options of a command (:mod:`labcli.commands._declared`),
the ``sim://`` URL's options and the one sentence that refuses an option a paper does not take.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import click
import pytest
from click.testing import CliRunner

from labcli.commands._declared import DeclaredCommand, Group, click_options
from labcli.core import registry
from labcli.core.options import (
    BadValue,
    Option,
    OptionRefused,
    Typed,
    bind,
    build,
    choice,
    declared,
    integer,
    number,
    path,
    switch,
    text,
)
from labcli.errors import ConfigError


def _pair(t: str) -> tuple[float, float]:
    a, b = (float(v) for v in t.split(","))
    if b < a:
        raise BadValue(f"{t} runs backwards; give LOW,HIGH.")
    return a, b


@dataclass(frozen=True)
class Sample:
    gain: float = number(2.0, help="Gain.", units="V/V", minimum=0, above=True)
    count: int | None = integer(help="How many.", minimum=1, maximum=9)
    verbose: bool = switch(help="Say more.")
    shape: str = choice(("round", "square"), "round", help="Shape.")
    out: Path | None = path(help="Where to write.")
    span: tuple[float, float] | None = text(help="A span.", parse=_pair, what="LOW,HIGH in mm", form="LOW,HIGH")
    tags: tuple[str, ...] = text((), help="Tags.", repeat=True, flag="--tag")


def test_a_declaration_reads_back_in_field_order_with_names_filled_in():
    decls = declared(Sample)
    assert [d.name for d in decls] == ["gain", "count", "verbose", "shape", "out", "span", "tags"]
    assert [d.cli_flag for d in decls][:2] == ["--gain", "--count"] and decls[-1].cli_flag == "--tag"
    assert decls[0].units == "V/V" and decls[0].default == 2.0
    assert Sample() == Sample(2.0, None, False, "round", None, None, ())
    with pytest.raises(dataclasses.FrozenInstanceError):
        Sample().gain = 3.0  # type: ignore[misc]


@pytest.mark.parametrize(
    "name,text,value",
    [
        ("gain", "1.5", 1.5),
        ("count", "9", 9),
        ("verbose", "1", True),
        ("verbose", "0", False),
        ("shape", "square", "square"),
        ("out", "a/b.png", Path("a/b.png")),
        ("span", "1,2", (1.0, 2.0)),
    ],
)
def test_each_kind_reads_its_text_form(name, text, value):
    assert {d.name: d for d in declared(Sample)}[name].read(text) == value


@pytest.mark.parametrize(
    "name,text,accepted",
    [
        ("gain", "0", "a number > 0"),
        ("gain", "nan", "a number > 0"),
        ("gain", "inf", "a number > 0"),
        ("count", "10", "a whole number within 1..9"),
        ("count", "1.5", "a whole number within 1..9"),
        ("verbose", "yes", "0 or 1"),
        ("shape", "oval", "one of round, square"),
        ("out", "", "the path of a file"),
        ("span", "x", "LOW,HIGH in mm"),
    ],
)
def test_each_kind_refuses_what_it_does_not_take_and_says_what_it_takes(name, text, accepted):
    decl = {d.name: d for d in declared(Sample)}[name]
    with pytest.raises(ValueError):
        decl.read(text)
    assert decl.accepted == accepted


def test_a_parser_can_refuse_in_its_own_words():
    decl = {d.name: d for d in declared(Sample)}["span"]
    with pytest.raises(BadValue, match="^2,1 runs backwards; give LOW,HIGH.$"):
        decl.read("2,1")


def test_help_names_units_and_defaults():
    decls = {d.name: d for d in declared(Sample)}
    assert decls["gain"].help_text() == "Gain.  [units: V/V; default: 2.0]"
    assert decls["verbose"].help_text() == "Say more."
    assert decls["shape"].help_text() == "Shape.  [default: round]"


def test_build_refuses_a_name_the_declaration_does_not_hold():
    assert build(Sample, {"gain": 3.0}).gain == 3.0
    with pytest.raises(ValueError, match="Sample declares no option 'gian'"):
        build(Sample, {"gian": 3.0})


def test_a_field_made_without_the_helpers_is_not_a_declaration():
    @dataclass(frozen=True)
    class Loose:
        x: int = 0

    with pytest.raises(TypeError, match="Loose.x is not a declared option"):
        declared(Loose)
    with pytest.raises(ValueError, match="a choice option needs its choices"):
        Option("choice")


def test_bind_refuses_an_undeclared_option_in_one_sentence_naming_who_takes_it():
    typed = Typed({"gain": 4.0, "form": "paper"}, {"form": "--form"})
    with pytest.raises(OptionRefused) as e:
        bind(Sample, typed, owners=lambda n: ["takuma2014 runs"], subject="x.h5 is a run of kind toy (toy)")
    assert str(e.value) == "--form is an option of takuma2014 runs; x.h5 is a run of kind toy (toy)."
    assert isinstance(e.value, ConfigError)
    with pytest.raises(OptionRefused, match="^--gain is an option of another paper; s.$"):
        bind(None, Typed({"gain": 4.0}), owners=lambda n: [], subject="s")
    assert bind(Sample, Typed({"gain": 4.0}), owners=lambda n: [], subject="s") == Sample(gain=4.0)


def test_a_required_option_left_out_is_refused():
    @dataclass(frozen=True)
    class Needs:
        model: Path = path(help="Model.", required=True)

    with pytest.raises(OptionRefused, match="^Missing option '--model'; s.$"):
        bind(Needs, Typed(), owners=lambda n: [], subject="s")


# --------------------------------------------------------------------------- as click options


@dataclass(frozen=True)
class Other:
    gain: float = number(help="Another paper's gain.", units="V/V", minimum=0, above=True)
    mode: str = choice(("a", "b"), "a", help="Mode.")


@dataclass(frozen=True)
class Clash:
    gain: str = choice(("low", "high"), help="A gain by name.")


def _command(groups):
    @click.command("demo-cmd", cls=DeclaredCommand, groups=lambda: groups, version=lambda: 0)
    @click.option("--json", "as_json", is_flag=True)
    def cmd(as_json: bool, typed: Typed) -> None:
        click.echo(repr(sorted(typed.values.items())))

    return cmd


def test_two_papers_declaring_one_option_alike_share_one_click_option_and_each_shows_its_help():
    cmd = _command([Group("Options of p1", declared(Sample)), Group("Options of p2", declared(Other))])
    shown = CliRunner().invoke(cmd, ["--help"]).output
    assert shown.count("--gain X") == 2 and "Another paper's gain." in shown and "Gain." in shown
    assert shown.index("Options of p1:") < shown.index("Options of p2:")
    out = CliRunner().invoke(cmd, ["--gain", "3", "--tag", "a", "--tag", "b", "--verbose", "--span", "1,2"]).output
    assert out == "[('gain', 3.0), ('span', (1.0, 2.0)), ('tags', ('a', 'b')), ('verbose', True)]\n"
    assert CliRunner().invoke(cmd, []).output == "[]\n"  # defaults are not typed: the paper fills them in


def test_click_refuses_a_malformed_value_with_the_declarations_words():
    cmd = _command([Group("Options of p1", declared(Sample))])
    result = CliRunner().invoke(cmd, ["--span", "2,1"])
    assert result.exit_code == 2 and "Invalid value for '--span': 2,1 runs backwards; give LOW,HIGH." in result.output
    result = CliRunner().invoke(cmd, ["--span", "x"])
    assert "Invalid value for '--span': must be LOW,HIGH in mm, got 'x'." in result.output
    result = CliRunner().invoke(cmd, ["--shape", "oval"])
    assert "'oval' is not one of 'round', 'square'" in result.output


def test_papers_declaring_one_option_differently_or_a_commands_own_are_refused():
    with pytest.raises(ValueError, match="Options of p1 and Options of p3 declare --gain differently"):
        click_options([Group("Options of p1", declared(Sample)), Group("Options of p3", declared(Clash))], "x", set())

    @dataclass(frozen=True)
    class TakesJson:
        json: bool = switch(help="Mine.")

    with pytest.raises(ValueError, match="declare --json, an option labcli x has of its own"):
        click_options([Group("Options of p4", declared(TakesJson))], "x", {"as_json", "--json"})


@pytest.mark.parametrize("command", ["fit", "validate", "classify", "optimize"])
def test_the_installed_papers_declarations_make_one_command_line(command):
    from labcli.commands._declared import analysis_groups

    groups = analysis_groups(command)
    assert groups, command
    built = click_options(groups, command, {"as_json", "--json", "protocol", "--protocol", "output", "--output"})
    assert {o.name for o in built} == {d.name for g in groups for d in g.options}


def test_the_registry_answers_from_the_declarations():
    assert set(registry.analysis_options("fit")) == {"rpam2015", "takuma2014"}
    assert set(registry.analysis_options("optimize")) == {"rpam2015"}
    assert registry.default_protocol("optimize") == "rpam2015"
    assert registry.experiments() == {"stretch": "rpam-stretch", "joint": "rpam-joint"}
    assert set(registry.sim_options("rpam")) == {"experiment", "nominal", "reading"}
    assert registry.modes_taking("supply") == ["mckibben"]
    with pytest.raises(ConfigError, match="Exactly one paper must name the default protocol of labcli no-such-command"):
        registry.default_protocol("no-such-command")
    with pytest.raises(ValueError, match="the rpam rig has no option 'supply'"):
        registry.make_rig("rpam", supply=(0.3,) * 4)
