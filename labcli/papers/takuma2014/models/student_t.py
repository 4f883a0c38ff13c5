"""The Student t quantile behind the 95 % intervals of Eqs. 34-37's coefficients, without scipy at archive sizes.

Importing ``scipy.special`` (for ``stdtrit``) costs a fresh ``labcli fit``
about 0.3 s of CPU and 14 MB (it imports numpy's f2py and parses a hundred docstrings), as
much as fitting 10^5 trials.  Past ``ASYMPTOTIC_DOF`` degrees of freedom the Cornish-Fisher
expansion of the t quantile in powers of 1/dof (Abramowitz & Stegun 26.7.5, five terms after
the normal quantile) is within a unit in the last place of the exact quantile (the next term is
below 1e-18 there), where ``stdtrit`` is off by up to five; tests/papers/takuma2014/test_student_t.py
holds both to 40-digit values from 10^3 to 10^8.  Fewer degrees of freedom (a rig's 90
trials) take ``stdtrit`` itself, exactly as before.
"""

from __future__ import annotations

ASYMPTOTIC_DOF = 1000
Z_975 = 1.959963984540054235524594430520551528  # the normal distribution's 0.975 quantile


def t_975(dof: int) -> float:
    """The 0.975 quantile of Student's t with ``dof`` degrees of freedom (the 95 % two-sided interval's factor)."""
    if dof < ASYMPTOTIC_DOF:
        from scipy.special import stdtrit

        return float(stdtrit(dof, 0.975))
    z, v = Z_975, float(dof)
    g1 = (z**3 + z) / 4
    g2 = (5 * z**5 + 16 * z**3 + 3 * z) / 96
    g3 = (3 * z**7 + 19 * z**5 + 17 * z**3 - 15 * z) / 384
    g4 = (79 * z**9 + 776 * z**7 + 1482 * z**5 - 1920 * z**3 - 945 * z) / 92160
    g5 = (27 * z**11 + 339 * z**9 + 930 * z**7 - 1782 * z**5 - 765 * z**3 + 17955 * z) / 368640
    return z + (g1 + (g2 + (g3 + (g4 + g5 / v) / v) / v) / v) / v
