"""The reading of Eq. 35's sign and the sign of the paper's forces, measured on the simulated rig."""

from __future__ import annotations

from labcli.papers.takuma2014.models.takuma import PAPER_COEFFICIENTS
from labcli.papers.takuma2014.sim.nonideal import NonIdeal
from labcli.papers.takuma2014.sim.paper_scale import paper_ratios
from labcli.papers.takuma2014.sim.rig import SimRig


def test_listed_minus_sign_of_beta_theta2_R2_reads_theta2_with_the_right_sign():
    # Section 3.3's -2.972 with Eq. 31's plus sign: theta2 comes out with the truth's sign and
    # about its size; Eq. 35's printed minus folded in (+2.972) reverses it.
    assert PAPER_COEFFICIENTS["beta_theta2_R2"] == -2.972
    # The kind rig (realism=kind): on the literature's rig (seed 1) the signs hold (theta2 +1.18 and
    # -0.66) but the paper's Fx reads -0.57 times the truth, outside the size bound below.
    kind = NonIdeal(realism="kind")
    eq31 = paper_ratios(SimRig(seed=1, nonideal=kind), "eq31")
    eq35 = paper_ratios(SimRig(seed=1, nonideal=kind), "eq35")
    assert 1.0 < eq31["theta2"]["median"] < 2.0, eq31["theta2"]
    assert -1.0 < eq35["theta2"]["median"] < -0.4, eq35["theta2"]
    # Eq. 14 gives the force the arm exerts on the load: the paper's Fx is minus the applied pull.
    assert -1.2 < eq31["Fx"]["median"] < -0.6
    assert eq31["theta1"]["median"] > 0.5
