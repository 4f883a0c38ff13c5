"""The t quantile of the coefficients' 95 % intervals: the asymptotic series against exact values and scipy."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.special import stdtrit

from labcli.papers.takuma2014.models.student_t import ASYMPTOTIC_DOF, t_975

# The 0.975 quantile to 25 digits: the root of I_{v/(v+t^2)}(v/2, 1/2) / 2 = 0.025, solved with
# 40-digit arithmetic (mpmath.betainc and findroot).
EXACT = (
    (1000, "1.96233908082640848499858"),
    (1001, "1.962336705280879918483966"),
    (2500, "1.96091334479556725804029"),
    (10000, "1.96020123989062625783848"),
    (123457, "1.959983200089538397411716"),
    (1000000, "1.959966356814107035258961"),
    (4000000, "1.959964577608038216368707"),
    (100000000, "1.959964008262766820760086"),
)


@pytest.mark.parametrize("dof, exact", EXACT)
def test_the_series_is_within_one_unit_in_the_last_place_of_the_exact_quantile(dof, exact):
    value = t_975(dof)
    assert abs(value - float(exact)) <= math.ulp(value)


def test_it_agrees_with_scipy_where_it_replaces_it_and_is_scipy_below():
    dofs = np.unique(np.logspace(3, 9, 400).astype(int))
    got = np.array([t_975(int(v)) for v in dofs])
    want = stdtrit(dofs, 0.975)
    # stdtrit itself is off by up to a few units in the last place here (against EXACT above).
    assert np.all(np.abs(got - want) <= 8 * np.spacing(want))
    for dof in (1, 2, 5, 88, ASYMPTOTIC_DOF - 1):
        assert t_975(dof) == float(stdtrit(dof, 0.975))
    assert t_975(1) == pytest.approx(12.706204736174698)  # the textbook table's 12.706
