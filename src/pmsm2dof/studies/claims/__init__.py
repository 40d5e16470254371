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
from collections.abc import Callable
from typing import TYPE_CHECKING

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
    OnDrive,
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

if TYPE_CHECKING:
    from ..paper_drive import DriveStudies

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
    "OnDrive",
    "compute_claims",
    "fmt",
]


#: The claims of the experiments (section 4.2), checked on a drive's runs too: claim -> the runs it uses.
ON_DRIVE: dict[Callable[[st.Studies], Claim], tuple[str, ...]] = {
    _claim_e1: ("e1-1dof-none", "e1-1dof-back_calculation"),
    _claim_e2: ("e2-1dof", "e2-2dof"),
    _claim_e3: ("e3-1dof", "e3-2dof"),
}


def _on_drive(check: Callable[[st.Studies], Claim], studies: st.Studies, drive: "DriveStudies") -> OnDrive:
    """``check`` applied to the drive's runs in place of the simulated ones (the same rule, the same figures)."""
    runs = ON_DRIVE[check]
    played = dataclasses.replace(
        studies,
        results={**studies.results, **{n: drive.results[n] for n in runs}},
        metrics={**studies.metrics, **{n: drive.metrics[n] for n in runs}},
    )
    claim = check(played)
    return OnDrive(
        measured=claim.measured,
        values=claim.values,
        verdict=claim.verdict,
        link=drive.link,
        speed_difference=max(float(drive.comparisons[n]["speed"]["relative_to_step"]) for n in runs),
    )


def compute_claims(studies: st.Studies, drive: "DriveStudies | None" = None) -> list[Claim]:
    """Every claim of the paper, checked against ``studies`` (:func:`pmsm2dof.studies.paper.run_studies`).

    With ``drive`` (:func:`pmsm2dof.studies.paper_drive.run_on_drives`), the claims of the
    experiments are also checked on the drive's runs (:attr:`Claim.on_drive`).

    Returns
    -------
    list of Claim
    """
    if drive is not None:
        missing = [n for runs in ON_DRIVE.values() for n in runs if n not in drive.results]
        if missing:
            raise ValueError(f"the drive's studies lack the runs {', '.join(missing)}")
    checks: list[Callable[[st.Studies], Claim]] = [
        _claim_gains,
        _claim_separate,
        _claim_first_order,
        _claim_fig7,
        _claim_lowpass,
        _claim_ka_range,
        _claim_unwind,
        _claim_tustin,
        _claim_limit_reached,
        _claim_no_aw_overshoot,
        _claim_current_reverse,
        _claim_aw_overshoot,
        _claim_1dof_load,
        _claim_c2_tracking,
        _claim_c2_load,
        _claim_e1,
        _claim_e2,
        _claim_e3,
        _claim_aw_everywhere,
        _claim_2dof_everywhere,
    ]
    claims = []
    for check in checks:
        claim = check(studies)
        if drive is not None and check in ON_DRIVE:
            claim = dataclasses.replace(claim, on_drive=_on_drive(check, studies, drive))
        claims.append(claim)
    claims.append(_claim_implementation())
    return [dataclasses.replace(c, id=f"C{k}") for k, c in enumerate(claims, start=1)]
