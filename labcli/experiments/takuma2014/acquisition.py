"""How a McKibben run is acquired: the force trials of a plan (or typed), or the pushes of objects."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Sequence

from ...core.experiment import AcquireOptions, Session
from ...errors import ConfigError
from .protocol import load_plan
from .session import force_session, push_session
from .sim.objects import demo_plan
from .tables import load_plan as read_plan


@dataclass
class ForceAcquisition:
    """Section 3.2: one trial per row of the plan (None: the experimenter types each load)."""

    protocol: Any
    plan: Any
    kind: str = "force"

    def session(self, completed: Sequence[int]) -> Session:
        return force_session(self.protocol, self.plan, completed=completed)

    def already_done(self, run: Any, path: str) -> str | None:
        plan = self.plan
        if plan is None or not len(plan) or run.first_incomplete(plan["trial"]) is not None:
            return None
        if run.split() is None:
            # Stopped between the last trial and the split: finish the job.
            sets = dict(zip(plan["trial"].astype(int), plan["set"]))
            run.set_split([t for t, v in sets.items() if v == "fit"],
                          [t for t, v in sets.items() if v == "validation"], "plan")
        return f"All {len(plan)} planned trials are already stored in {path}; nothing to resume."


@dataclass
class PushAcquisition:
    """Section 4: ``pushes_per_object`` pushes per object (typed, or the simulated objects)."""

    protocol: Any
    objects: Any = None
    kind: str = "push"
    plan: Any = None

    def session(self, completed: Sequence[int]) -> Session:
        return push_session(self.protocol, self.objects, completed=completed)

    def already_done(self, run: Any, path: str) -> str | None:
        return None


def _plan(protocol: Any, options: AcquireOptions) -> Any:
    """The plan a force run follows: the run's own when resuming, a file, typed, or the protocol's."""
    if options.resume is not None:
        return options.resume.plan_table()
    if options.no_plan:
        return None
    if options.plan is not None:
        lim = protocol.settings.force_limits
        return read_plan(
            options.plan,
            mass_range_g=(lim.mass_min_g, lim.mass_max_g) if lim else None,
            direction_range_deg=(lim.direction_min_deg, lim.direction_max_deg) if lim else None,
        )
    return load_plan(protocol)


def acquisition(protocol: Any, options: AcquireOptions) -> ForceAcquisition | PushAcquisition:
    """Plan a run of a ``force`` or ``push`` protocol."""
    if protocol.kind == "push":
        objects = None
        if options.unattended:
            # The simulated rig's reference objects (three PET bottles, two aluminium
            # cans, one steel can), labelled with their categories.
            push = protocol.settings.push
            objects = demo_plan(pushes_per_object=push.pushes_per_object if push else 10, labelled=True)
        return PushAcquisition(protocol, objects)
    plan = _plan(protocol, options)
    if options.unattended and plan is None:
        if options.resume is not None:
            how = ("it was imported from a table" if options.resume.attrs.get("imported")
                   else "it was recorded with --no-plan")
            raise ConfigError(
                f"{options.path} has no plan ({how}), so --unattended has nothing to follow; "
                "resume it without --unattended and type each load."
            )
        raise ConfigError("--unattended needs a plan to follow: drop --no-plan, or give --plan FILE.")
    return ForceAcquisition(protocol, plan)
