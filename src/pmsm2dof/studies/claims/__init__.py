"""The claims of the paper, checked against what the reproduction measured.

:func:`compute_claims` checks every claim of the paper (sections 3, 4.1, 4.2 and 5) against the
studies of :mod:`pmsm2dof.studies.paper`: each :class:`Claim` holds the paper's value, the
measured one, a verdict (:data:`VERDICTS`) and the reason where they differ. Every measured value
is computed from the simulation results (or, for design claims, from the transfer functions of
:mod:`pmsm2dof.analysis.design`); the verdict rules are the constants of :mod:`.common`. The presets are never
tuned to meet a number of the paper: where a number differs, the reason says which parameter the
paper does not give and what the sensitivity studies show about it.

Reference: Wang, Lin, Yang, Fang, "Anti-Windup and 2DOF Design for Permanent-Magnet Synchronous
Motor Speed Controller" (equation, figure and section numbers are the paper's).
"""

import dataclasses

from .. import paper as st
from .common import (
    ABOUT_RTOL,
    AW_TOLERANCE_PP,
    FIG7_M,
    FIRST_ORDER_RTOL,
    NO_OVERSHOOT_PCT,
    SAME_RTOL,
    SOURCES,
    VERDICTS,
    Claim,
    fmt,
)
from .design import (
    _claim_fig7,
    _claim_first_order,
    _claim_gains,
    _claim_ka_range,
    _claim_lowpass,
    _claim_separate,
    _claim_tustin,
    _claim_unwind,
)
from .simulation import (
    _claim_1dof_load,
    _claim_2dof_everywhere,
    _claim_aw_everywhere,
    _claim_aw_overshoot,
    _claim_c2_load,
    _claim_c2_tracking,
    _claim_current_reverse,
    _claim_e1,
    _claim_e2,
    _claim_e3,
    _claim_implementation,
    _claim_limit_reached,
    _claim_no_aw_overshoot,
)

__all__ = [
    "ABOUT_RTOL",
    "AW_TOLERANCE_PP",
    "FIG7_M",
    "FIRST_ORDER_RTOL",
    "NO_OVERSHOOT_PCT",
    "SAME_RTOL",
    "SOURCES",
    "VERDICTS",
    "Claim",
    "compute_claims",
    "fmt",
]


def compute_claims(studies: st.Studies) -> list[Claim]:
    """Every claim of the paper, checked against ``studies`` (:func:`pmsm2dof.studies.paper.run_studies`).

    Returns
    -------
    list of Claim
    """
    claims = [
        _claim_gains(studies),
        _claim_separate(studies),
        _claim_first_order(studies),
        _claim_fig7(studies),
        _claim_lowpass(studies),
        _claim_ka_range(studies),
        _claim_unwind(studies),
        _claim_tustin(studies),
        _claim_limit_reached(studies),
        _claim_no_aw_overshoot(studies),
        _claim_current_reverse(studies),
        _claim_aw_overshoot(studies),
        _claim_1dof_load(studies),
        _claim_c2_tracking(studies),
        _claim_c2_load(studies),
        _claim_e1(studies),
        _claim_e2(studies),
        _claim_e3(studies),
        _claim_aw_everywhere(studies),
        _claim_2dof_everywhere(studies),
        _claim_implementation(),
    ]
    return [dataclasses.replace(c, id=f"C{k}") for k, c in enumerate(claims, start=1)]
