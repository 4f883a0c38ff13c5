"""Options declared by the papers (:mod:`labcli.core.options`), as click options of a command.

A :class:`DeclaredCommand` is a click command whose options are its own plus those the
installed papers declare for it (read from the registry when the command is parsed or its
help shown, never for ``labcli --help``; rebuilt when a paper is registered at run time).
An option two papers declare alike is one click option; its help shows under each paper.
The callback receives the declared options a person typed as one
:class:`~labcli.core.options.Typed` argument named ``typed``; the core then binds them to
the paper that reads the inputs and refuses the others in one sentence.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import click
from click.core import ParameterSource

from ..core.options import BadValue, Option, Typed
from ..errors import LabcliError
from ._options import FiniteRange


@dataclass(frozen=True)
class Group:
    """The options one paper (or one paper's rigs) declares for a command, under a title for ``--help``."""

    title: str
    options: tuple[Option, ...]


class DeclaredType(click.ParamType):
    """A value read by the declaration's own reader (a custom parser or a text form)."""

    def __init__(self, decl: Option) -> None:
        self.decl = decl
        self.name = decl.metavar

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        if not isinstance(value, str):
            return value
        try:
            return self.decl.read(value)
        except BadValue as e:
            self.fail(str(e), param, ctx)
        except ValueError:
            self.fail(f"must be {self.decl.accepted}, got '{value}'.", param, ctx)


def click_type(decl: Option) -> Any:
    """The click type of a declared option (click's own where one fits, so its messages stay click's)."""
    if decl.parse is not None or decl.kind == "text":
        return DeclaredType(decl)
    if decl.kind == "choice":
        return click.Choice(list(decl.choices))
    if decl.kind == "path":
        return click.Path(dir_okay=False, path_type=Path)
    if decl.kind == "integer":
        return click.IntRange(decl.minimum, decl.maximum)  # type: ignore[arg-type]
    return FiniteRange(decl.minimum, decl.maximum, min_open=decl.above)


def _shape(decl: Option) -> tuple[Any, ...]:
    """What two declarations of one option must share to be one click option."""
    return (decl.kind, decl.choices, decl.cli_flag, decl.repeat, decl.parse, decl.minimum, decl.maximum, decl.above)


def click_options(groups: Sequence[Group], command: str, taken: set[str]) -> list[click.Option]:
    """One hidden click option per declared name over the groups (their help is the groups').

    ConfigError-like ValueError when two papers declare one name differently, or a paper
    declares an option the command has of its own (``taken``).
    """
    first: dict[str, tuple[str, Option]] = {}
    out: list[click.Option] = []
    for group in groups:
        for decl in group.options:
            if decl.name in taken or decl.cli_flag in taken:
                raise ValueError(f"{group.title} declare {decl.cli_flag}, an option labcli {command} has of its own")
            if decl.name in first:
                title, other = first[decl.name]
                if _shape(other) != _shape(decl):
                    raise ValueError(f"{title} and {group.title} declare {decl.cli_flag} differently")
                continue
            first[decl.name] = (group.title, decl)
            holders = [o for g in groups for o in g.options if o.name == decl.name]
            # Required of the command only when every paper offering it requires it; else the core asks.
            required = len(holders) == len(groups) and all(o.required for o in holders)
            # is_flag only for a switch: an explicit is_flag=False makes click take the value as optional.
            kind = {"is_flag": True} if decl.kind == "switch" else {"type": click_type(decl), "metavar": decl.metavar}
            out.append(
                click.Option([decl.cli_flag, decl.name], multiple=decl.repeat, required=required, hidden=True, **kind)
            )
    return out


def help_record(decl: Option) -> tuple[str, str]:
    flag = decl.cli_flag if decl.kind == "switch" else f"{decl.cli_flag} {decl.metavar}"
    return flag, decl.help_text()


class DeclaredCommand(click.Command):
    """A command with the papers' declared options beside its own (see the module's docstring)."""

    def __init__(self, *args: Any, groups: Callable[[], list[Group]], version: Callable[[], int], **kw: Any) -> None:
        super().__init__(*args, **kw)
        self._groups, self._version = groups, version
        self._built: tuple[int, list[Group], list[click.Option]] | None = None

    def declared(self) -> tuple[list[Group], list[click.Option]]:
        """The groups of declared options and their click options (rebuilt when the papers change)."""
        version = self._version()
        if self._built is None or self._built[0] != version:
            groups = self._groups()
            taken = {p.name for p in self.params if p.name} | {o for p in self.params for o in p.opts}
            try:
                built = click_options(groups, str(self.name), taken)
            except ValueError as e:
                raise click.ClickException(f"The papers' options cannot be put together: {e}.") from None
            self._built = (version, groups, built)
        return self._built[1], self._built[2]

    def get_params(self, ctx: click.Context) -> list[click.Parameter]:
        help_option = self.get_help_option(ctx)
        return [*self.params, *self.declared()[1], *([help_option] if help_option is not None else [])]

    def invoke(self, ctx: click.Context) -> Any:
        values: dict[str, Any] = {}
        flags: dict[str, str] = {}
        for opt in self.declared()[1]:
            name = str(opt.name)
            value = ctx.params.pop(name, None)
            if ctx.get_parameter_source(name) in (ParameterSource.COMMANDLINE, ParameterSource.ENVIRONMENT):
                values[name] = tuple(value) if opt.multiple else value
                flags[name] = opt.opts[0]
        ctx.params["typed"] = Typed(values, flags)
        return super().invoke(ctx)

    def format_options(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        super().format_options(ctx, formatter)
        for group in self.declared()[0]:
            if group.options:
                with formatter.section(group.title):
                    formatter.write_dl([help_record(o) for o in group.options])


def analysis_groups(command: str) -> list[Group]:
    """The options each paper offering ``command`` declares for it, one group per paper."""
    from ..core import registry
    from ..core.options import declared

    out = []
    for paper in registry.papers():
        cls = paper.analysis_options.get(command)
        if cls is not None:
            kinds = ", ".join(paper.run_kinds)
            out.append(Group(f"Options of {paper.name} ({kinds})", declared(cls)))
    return out


def sensing_groups() -> list[Group]:
    """The options each paper declares for ``labcli sense`` with its model files, one group per paper."""
    from ..core.options import declared
    from ..sensing.model import sensing_papers

    return [
        Group(f"Options of {p.name} models", declared(p.sensing_options))
        for p in sensing_papers()
        if p.sensing_options is not None
    ]


def rig_groups() -> list[Group]:
    """The options each paper declares for its simulated rigs, one group per paper."""
    from ..core import registry
    from ..core.options import declared

    return [
        Group(f"Options of the {', '.join(p.sim_modes)} rig (--mode {'|'.join(p.sim_modes)})", declared(p.sim_options))
        for p in registry.papers()
        if p.sim_options is not None
    ]


def _version() -> int:
    from ..core import registry

    return registry.generation()


def paper_command(
    name: str | None = None, groups: Callable[[], list[Group]] | None = None
) -> Callable[[Callable[..., Any]], Any]:
    """``@paper_command("fit")``: a click command taking the options the papers declare for
    ``name``'s analysis; ``@paper_command(groups=sensing_groups)``: those ``groups`` gives (the
    command named after its function)."""
    if groups is None:
        if name is None:
            raise TypeError("paper_command needs the analysis's name or the groups of options")
        analysis = name
        groups = lambda: analysis_groups(analysis)  # noqa: E731
    return click.command(name, cls=DeclaredCommand, groups=groups, version=_version)


def _default_protocol(command: str) -> dict[str, str]:
    from ..core import registry

    try:
        return {"default": registry.default_protocol(command)}
    except LabcliError:
        return {"default": "none"}


def protocol_option(command: str, template: str, **kw: Any) -> Callable[[Any], Any]:
    """``--protocol`` for ``command``; ``template``'s ``{default}`` is the registry's default protocol for it."""
    return click.option(
        "--protocol", cls=RegistryHelpOption, template=template, fill=lambda: _default_protocol(command), **kw
    )


class RegistryChoice(click.Choice):
    """A choice whose values the registry gives when the command is parsed or its help shown."""

    def __init__(self, values: Callable[[], Sequence[str]]) -> None:
        super().__init__([])
        self._values = values

    @property  # type: ignore[override]
    def choices(self) -> Sequence[str]:
        return list(self._values())

    @choices.setter
    def choices(self, value: Sequence[str]) -> None:
        pass


class RegistryHelpOption(click.Option):
    """An option whose help is filled in from the registry when shown (``template.format(**fill())``)."""

    def __init__(self, *args: Any, template: str, fill: Callable[[], dict[str, str]], **kw: Any) -> None:
        super().__init__(*args, **kw)
        self.template, self.fill = template, fill

    def get_help_record(self, ctx: click.Context) -> tuple[str, str] | None:
        self.help = self.template.format(**self.fill())
        return super().get_help_record(ctx)


def _experiments() -> dict[str, str]:
    from ..core import registry

    holders = " or ".join(k.described_as for k in registry.protocol_kinds().values() if k.experiments)
    choices = " or ".join(f"{c} (a run of kind {kind})" for c, kind in registry.experiments().items())
    return {"holders": holders or "a protocol holding several", "choices": choices or "none installed"}


def experiment_option(template: str) -> Callable[[Any], Any]:
    """``--experiment``: its choices the experiments the papers' protocol kinds hold (``{holders}``, ``{choices}``)."""
    from ..core import registry

    return click.option(
        "--experiment",
        cls=RegistryHelpOption,
        type=RegistryChoice(lambda: list(registry.experiments())),
        default=None,
        template=template,
        fill=_experiments,
    )


def shipped_protocols() -> dict[str, str]:
    """``{shipped}``: the protocols the installed papers ship, for help texts."""
    from ..core import registry

    return {"shipped": ", ".join(n for p in registry.papers() for n in p.shipped_protocols)}
