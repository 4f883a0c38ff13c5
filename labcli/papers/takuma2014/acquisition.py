"""How a McKibben run is acquired: the force trials of a plan (or typed), or the pushes of objects
(typed, from a push plan, or the simulated objects)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

from ...core.paper import AcquireOptions, Session
from ...core.protocol import with_acquisition_key, with_captures
from ...core.words import count
from ...errors import ConfigError
from .protocol import CAPTURE_KINDS, load_plan
from .push_plan import load_push_plan, plan_objects
from .push_session import push_session
from .session import PRESSURE_NAMES, force_session, planned_trials
from .sim.objects import demo_plan
from .tables import load_plan as read_plan


@dataclass
class ForceAcquisition:
    """Section 3.2: one trial per row of the plan (None: the experimenter types each load)."""

    protocol: Any
    plan: Any
    kind: str = "force"
    history: tuple = ()  # (force N, change SI) of the trials a resumed run already holds
    baselines: tuple = ()  # their baselines (SI, the load check's watched channels)

    def session(self, completed: Sequence[int]) -> Session:
        return force_session(
            self.protocol, self.plan, completed=completed, history=self.history, baselines=self.baselines
        )

    def already_done(self, run: Any, path: str) -> str | None:
        plan = self.plan
        if plan is None or not len(plan):
            return None
        rows = planned_trials(plan, self.protocol.air.captures_per_load)
        if run.records.first_incomplete(r.trial for r in rows) is not None:
            return None
        if run.split.get() is None:
            # Stopped between the last trial and the split: finish the job.
            sets = {r.trial: r.set for r in rows}
            run.split.set(
                [t for t, v in sets.items() if v == "fit"], [t for t, v in sets.items() if v == "validation"], "plan"
            )
        n = self.protocol.air.captures_per_load  # a trial is a plan load, of n captures (records)
        trials = f"{len(rows)} planned trials"
        if n > 1:
            trials = f"{len(rows)} captures of the {count(len(rows) // n, 'planned trial')}"
        return f"All {trials} are already stored in {path}; nothing to resume."


@dataclass
class PushAcquisition:
    """Section 4: ``pushes_per_object`` pushes per object (typed, a push plan, or the simulated objects)."""

    protocol: Any
    objects: Any = None
    kind: str = "push"
    plan: Any = None  # a push plan's table, stored in the run
    ids: Any = None  # the plan's push ids, in the order they are run

    def session(self, completed: Sequence[int]) -> Session:
        return push_session(self.protocol, self.objects, completed=completed, ids=self.ids)

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
        table = read_plan(
            options.plan,
            mass_range_g=(lim.mass_min_g, lim.mass_max_g) if lim else None,
            direction_range_deg=(lim.direction_min_deg, lim.direction_max_deg) if lim else None,
        )
        _not_empty(table, options.plan, ("trial", "trials"), "trial, set, mass_g, direction_deg")
        return table
    return load_plan(protocol)


def _not_empty(table: Any, path: Any, noun: tuple[str, str], columns: str) -> None:
    """Refuse a plan file that holds only its header: a run of nothing, or (pushes) the simulated objects
    in its place, would not be what was asked."""
    if not len(table):
        raise ConfigError(
            f"{path} holds no {noun[1]}, only its header; add a row per {noun[0]} ({columns}), or leave --plan out."
        )


def _push_acquisition(protocol: Any, options: AcquireOptions) -> PushAcquisition:
    """A push run: its plan (a file, or the one a resumed run stored), else the simulated objects
    (unattended), else objects typed at the rig."""
    push = protocol.settings.push
    table = options.resume.plan_table() if options.resume is not None else None
    if options.plan is not None:
        table = load_push_plan(
            options.plan, distance_range_m=(push.distance_min_m, push.distance_max_m) if push is not None else None
        )
        _not_empty(table, options.plan, ("push", "pushes"), "push, object, R_mm, d_mm, phi_deg")
    if table is not None and len(table):
        objects, ids = plan_objects(table)
        if options.unattended:
            bare = [o.spec.name for o in objects if o.spec.stiffness_N_per_m is None]
            if bare:
                raise ConfigError(
                    f"--unattended pushes simulated objects, whose stiffness the plan must give: "
                    f"column stiffness_N_per_m is empty for {', '.join(bare)}."
                )
        return PushAcquisition(protocol, objects, plan=table, ids=ids)
    if options.unattended:
        # The simulated rig's reference objects (three PET bottles, two aluminium
        # cans, one steel can), labelled with their categories.
        return PushAcquisition(
            protocol, demo_plan(pushes_per_object=push.pushes_per_object if push else 10, labelled=True)
        )
    return PushAcquisition(protocol)


def _history(run: Any, protocol: Any) -> tuple:
    """What a resumed run's stored trials did per newton: (Fx, Fy) N and the change of each
    pressure (MPa) and joint angle (rad) the load check watches, in the protocol's channel order."""
    import math

    watched = [c for c, u in zip(protocol.channels, protocol.calibration.units, strict=False) if u in ("MPa", "rad")]
    out = []
    for row in run.records.table().to_dict("records"):
        change = {p: row[p] - row[p + "0"] for p in PRESSURE_NAMES}
        change.update(POT1=math.radians(row["theta1_deg"]), POT2=math.radians(row["theta2_deg"]))
        values = [change.get(c, math.nan) for c in watched]
        if all(math.isfinite(v) for v in values):
            out.append(((row["Fx_N"], row["Fy_N"]), values))
    return tuple(out)


def _baselines(run: Any, protocol: Any) -> tuple:
    """A resumed run's stored baselines: each pressure (MPa) and joint angle (rad) the load check
    watches, in the protocol's channel order."""
    import math

    watched = [c for c, u in zip(protocol.channels, protocol.calibration.units, strict=False) if u in ("MPa", "rad")]
    out = []
    for row in run.records.table().to_dict("records"):
        base = {p: row[p + "0"] for p in PRESSURE_NAMES}
        base.update(POT1=math.radians(row["theta1_0_deg"]), POT2=math.radians(row["theta2_0_deg"]))
        values = [base.get(c, math.nan) for c in watched]
        if all(math.isfinite(v) for v in values):
            out.append(tuple(values))
    return tuple(out)


def _check_captures(protocol: Any, plan: Any) -> None:
    """More than one capture a load needs a plan of trials numbered from 1 (each capture's id, session.capture_id)."""
    n = protocol.air.captures_per_load
    if n == 1:
        return
    if plan is None:
        raise ConfigError(
            f"acquisition.captures_per_load = {n} takes each plan load {n} times; loads typed at the rig are "
            "captured once, so give a plan or set captures_per_load to 1."
        )
    low = int(plan["trial"].min()) if len(plan) else 1
    if low < 1:
        raise ConfigError(
            f"With acquisition.captures_per_load = {n} the plan's trials are numbered from 1 (each capture's "
            f"record id is (trial - 1) x {n} + capture), but the plan has trial {low}."
        )


def _captured(protocol: Any, options: AcquireOptions) -> Any:
    """A force protocol with ``--captures`` written in (a new run), or checked against the run's (a resumed
    one).  A push protocol is left as it is: the core refuses more than one capture for it
    (:func:`labcli.core.acquisition.check_captures`, in the words of ``single_captures``)."""
    n = options.captures
    if n is None or protocol.kind not in CAPTURE_KINDS:
        return protocol
    if options.resume is None:
        return with_captures(protocol, n)
    if protocol.air.captures_per_load != n:
        raise ConfigError(
            f"{options.path} was recorded with {count(protocol.air.captures_per_load, 'capture')} of each load, "
            f"not {n}; "
            "drop --captures to resume it, or start a new run."
        )
    return protocol


def _relief_vent(protocol: Any, options: AcquireOptions) -> Any:
    """A force protocol whose friction relief vents, with the side it vents settled: a new run's copy
    says it (``friction_relief_vent``, the default ``"load"`` written in), so that the run stores what
    it did; a resumed run keeps venting what it vented.  A stored protocol without the key was begun
    before the per-load default, and vented L, as did ``"load"`` where the rig's statics could not find
    the side (:meth:`PhysicsPrior.of` None); a new run asking for ``"load"`` there is refused in one
    sentence (docs/load-check.md)."""
    from .guard_prior import PhysicsPrior

    air = protocol.air
    if not air.friction_relief_vent_s > 0:
        return protocol
    if protocol.kind not in CAPTURE_KINDS:
        if air.friction_relief_vent == "load" and options.resume is None:
            # A push has no load for the statics to take a side from; it would vent L unsaid.
            raise ConfigError(
                f"The friction relief of {protocol.name} vents the side each load pulls the arm towards "
                '(acquisition.friction_relief_vent = "load", the default), and a push has no load to take it '
                'from: set friction_relief_vent = "L" or "R" to vent that side before every push.'
            )
        return protocol
    given = "friction_relief_vent" in protocol.sections.get("acquisition", {})
    per_load = air.friction_relief_vent == "load"
    if options.resume is not None:
        if given and (not per_load or PhysicsPrior.of(protocol) is not None):
            return protocol
        return replace(protocol, air=replace(air, friction_relief_vent="L"))
    if per_load and PhysicsPrior.of(protocol) is None:
        raise ConfigError(
            f"The friction relief of {protocol.name} vents the side each load pulls the arm towards "
            '(acquisition.friction_relief_vent = "load", the default), which the rig\'s statics find from its '
            "[rig] geometry and the channels P_L1, P_R1, P_L2, P_R2, POT1 and POT2, and the protocol does not "
            'name them all: name them so, or set friction_relief_vent = "L" or "R" to vent that side before '
            "every trial."
        )
    if given:
        return protocol
    return with_acquisition_key(
        protocol,
        'friction_relief_vent = "load"',
        f"{protocol.name} venting per load",
        'write friction_relief_vent = "load" there (or "L", "R"), so that the run records the side it vents',
    )


def acquisition(protocol: Any, options: AcquireOptions) -> ForceAcquisition | PushAcquisition:
    """Plan a run of a ``force`` or ``push`` protocol."""
    protocol = _relief_vent(_captured(protocol, options), options)
    if protocol.kind == "push":
        return _push_acquisition(protocol, options)
    plan = _plan(protocol, options)
    if options.unattended and plan is None:
        if options.resume is not None:
            how = (
                "it was imported from a table"
                if options.resume.attrs.get("imported")
                else "it was recorded with --no-plan"
            )
            raise ConfigError(
                f"{options.path} has no plan ({how}), so --unattended has nothing to follow; "
                "resume it without --unattended and type each load."
            )
        raise ConfigError("--unattended needs a plan to follow: drop --no-plan, or give --plan FILE.")
    _check_captures(protocol, plan)
    if options.resume is None:
        return ForceAcquisition(protocol, plan)
    return ForceAcquisition(
        protocol, plan, history=_history(options.resume, protocol), baselines=_baselines(options.resume, protocol)
    )
