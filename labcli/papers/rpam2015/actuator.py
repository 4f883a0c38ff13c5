"""The rPAM actuator as plain data: the one type the model, its fits, the optimiser and the
simulated stand share.

An rPAM (reverse pneumatic artificial muscle) is a silicone tube of wall section ``A0`` and
undeformed length ``L0`` inside a cage of inextensible thread (``n`` turns of a thread of
length ``b``), closed by two end caps; pressure extends it.  Its wall is a three-term Ogden
solid (Eq. 3 of the rPAM joint paper, in that equation's convention: initial shear modulus
``sum mu_i``); Eq. 7 adds an empirical stretch force, a cubic in ``lambda = L / L0`` fitted
to a stretch test over a range of stretches.

Units are the toolkit's SI: lengths in m, areas in m^2, forces in N; the Ogden moduli in
MPa, the unit of every pressure in labcli.  The type knows nothing of protocol files or JSON
documents beyond its own fields: :func:`labcli.papers.rpam2015.protocol.actuator_of` gives a
protocol's (its ``build`` makes one of the ``[actuator]``, ``[ogden]`` and
``[stretch_correction]`` tables: ``Protocol.settings.actuator``), :meth:`Actuator.from_dict`
reads the ``actuator`` record a model file keeps (a joint-map analysis's), and
:meth:`Actuator.with_stretch_correction` puts a fitted correction on it (what a stretch
fit's ``apply_to`` does).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, replace
from typing import Any

from ...errors import ModelError

# Eq. 7's correction is a cubic: four coefficients c0..c3.
STRETCH_TERMS = 4
# The two readings of Eqs. 1-3 (:mod:`labcli.papers.rpam2015.models.rpam_force`): the force
# derived from the wall's strain energy and the gas's virtual work, and the paper's lumen
# free body (cage term + P A0 / lambda + uniaxial Eq. 3).
FORCE_READINGS = ("derived", "paper")


@dataclass(frozen=True)
class Actuator:
    """One rPAM: undeformed length, wall section, thread cage, Ogden wall, stretch correction.

    ``L0_m``: length between the end caps, undeformed (m).
    ``A0_m2``: the wall's cross-section at rest (m^2); the wall fills the cage at rest.
    ``n_turns``: turns of the thread cage over ``L0_m``.
    ``thread_length_m``: the length ``b`` of one thread (m); the cage's radius at length L
    is ``sqrt(b^2 - L^2) / (2 pi n)``.
    ``ogden_mu_MPa``, ``ogden_alpha``: Eq. 3's moduli (MPa, each > 0) and exponents (each != 0).
    ``stretch_coefficients_N``: c0..c3 of Eq. 7's ``F_stretch = c0 + c1 l + c2 l^2 + c3 l^3`` (N,
    tension +); ``stretch_lambda_range``: the stretches ``[low, high]`` the cubic was fitted on
    (the model holds its end values outside; the simulated stand, whose correction is the
    truth, does not).
    ``force_reading``: which reading of Eqs. 1-3 gives the actuator's force, ``"derived"``
    (the potential of the cage-held wall and the gas) or ``"paper"`` (the lumen's free body
    with the uniaxial Eq. 3); see :mod:`labcli.papers.rpam2015.models.rpam_force`.  Moduli
    and corrections fitted under one reading belong to it, so it travels with them.
    """

    L0_m: float
    A0_m2: float
    n_turns: float
    thread_length_m: float
    ogden_mu_MPa: tuple[float, ...]
    ogden_alpha: tuple[float, ...]
    stretch_coefficients_N: tuple[float, ...] = (0.0,) * STRETCH_TERMS
    stretch_lambda_range: tuple[float, float] = (1.0, 2.2)
    force_reading: str = "derived"

    @property
    def rest_radius_m(self) -> float:
        """Radius of the thread cage at L = L0 (m): the wall's outer radius at rest."""
        return math.sqrt(max(self.thread_length_m**2 - self.L0_m**2, 0.0)) / (2 * math.pi * self.n_turns)

    @property
    def rest_helix_angle_rad(self) -> float:
        """Thread angle from the actuator axis at L = L0 (90 deg would be pure hoops)."""
        return math.acos(self.L0_m / self.thread_length_m)

    def problems(self) -> list[str]:
        """What makes this actuator unbuildable, as sentence bodies naming the protocol keys
        (``key 'actuator.A0_m2' must be less than ...``); empty when it is sound."""
        out: list[str] = []
        mu, al = self.ogden_mu_MPa, self.ogden_alpha
        if len(mu) != len(al) or not mu:
            out.append("keys 'ogden.mu_MPa' and 'ogden.alpha' must be lists of the same length")
        # Eq. 3's convention: W = sum 2 mu_i / alpha_i^2 (l1^alpha_i + l2^alpha_i + l3^alpha_i - 3),
        # convex (stable in every mode, not only in uniaxial tension) when every mu_i > 0.
        elif any(a == 0 for a in al) or any(m <= 0 for m in mu):
            out.append(
                "the Ogden constants need mu_i > 0 and alpha_i != 0 for every term (Eq. 3's convention; "
                "a negative mu_i makes the wall unstable outside uniaxial tension)"
            )
        if self.force_reading not in FORCE_READINGS:
            out.append(
                f"key 'actuator.force_reading' must be one of {', '.join(FORCE_READINGS)}, not {self.force_reading!r}"
            )
        if len(self.stretch_coefficients_N) != STRETCH_TERMS:
            out.append(f"key 'stretch_correction.coefficients_N' must hold {STRETCH_TERMS} coefficients c0..c3 in N")
        if self.thread_length_m <= self.L0_m:
            out.append(
                "key 'actuator.thread_length_m' must exceed actuator.L0_m: a thread shorter than the "
                "actuator cannot wind round it"
            )
        elif self.A0_m2 >= math.pi * self.rest_radius_m**2:
            out.append(
                "key 'actuator.A0_m2' must be less than the cage's section at rest, pi r^2 = "
                f"{math.pi * self.rest_radius_m**2:.4g} m^2 (r from actuator.n_turns and thread_length_m): "
                "the wall lies inside the thread cage"
            )
        return out

    def with_stretch_correction(
        self, coefficients_N: Sequence[float], lambda_range: Sequence[float] | None = None
    ) -> Actuator:
        """This actuator with another Eq. 7 cubic (a fitted one), and the stretches it holds for."""
        coef = tuple(float(c) for c in coefficients_N)
        if len(coef) != STRETCH_TERMS:
            raise ModelError(f"A stretch correction is {STRETCH_TERMS} coefficients c0..c3 in N, not {len(coef)}.")
        if lambda_range is None:
            return replace(self, stretch_coefficients_N=coef)
        lo, hi = (float(v) for v in lambda_range)
        return replace(self, stretch_coefficients_N=coef, stretch_lambda_range=(lo, hi))

    def with_force_reading(self, reading: str | None) -> Actuator:
        """This actuator read the other way (``"derived"`` or ``"paper"``); itself for None."""
        if reading is None or reading == self.force_reading:
            return self
        if reading not in FORCE_READINGS:
            raise ModelError(f"The actuator's force is read as {' or '.join(FORCE_READINGS)}, not {reading!r}.")
        return replace(self, force_reading=reading)

    def to_dict(self) -> dict[str, Any]:
        """The fields as JSON values (tuples as lists), the ``actuator`` record of a model file."""
        return {k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(self).items()}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> Actuator:
        """The actuator of a :meth:`to_dict` record (a model file's); :class:`ModelError` when
        the record is incomplete, malformed or describes no buildable actuator."""
        try:
            act = cls(
                L0_m=float(d["L0_m"]),
                A0_m2=float(d["A0_m2"]),
                n_turns=float(d["n_turns"]),
                thread_length_m=float(d["thread_length_m"]),
                ogden_mu_MPa=tuple(float(v) for v in d["ogden_mu_MPa"]),
                ogden_alpha=tuple(float(v) for v in d["ogden_alpha"]),
                stretch_coefficients_N=tuple(float(v) for v in d["stretch_coefficients_N"]),
                stretch_lambda_range=_pair(d["stretch_lambda_range"]),
                # Records written before the paper's reading existed were all derived.
                force_reading=str(d.get("force_reading", "derived")),
            )
        except (KeyError, TypeError, ValueError) as e:
            raise ModelError(f"The actuator record is incomplete or malformed ({e!s}).") from None
        bad = act.problems()
        if bad:
            raise ModelError(f"The actuator record describes no actuator that can be built: {bad[0]}.")
        return act


def _pair(v: Any) -> tuple[float, float]:
    lo, hi = (float(x) for x in v)
    return lo, hi
