"""The space the autotuner searches: its coarse grids, its bounds, and the most runs a search can make.

The grids and ranges are in the coordinates of :func:`pmsm2dof.studies.autotune_search.autotune`: zeta
(eq 9), alpha as a fraction of the edge (the largest bandwidth whose discrete loop meets the margins),
the back-calculation gain as ``Ka Kp`` (section 3.3) and the tracking pole factor m (eq 11).
"""

import itertools

import numpy as np

from ..sim.scenario import Scenario
from .autotune import Spec

#: Inertia ratios at which the margins are checked, and the best design is simulated again.
N_J_CHECK = 9
#: Relative damping of the coarse grid (eq 9).
ZETA_GRID = (0.3, 0.45, 0.67, 1.0, 1.4, 2.0)
#: Bandwidths of the coarse grid as fractions of the edge (the largest alpha the margins allow).
ALPHA_FRACTIONS = (1.0, 0.7, 0.4, 0.15)
#: Decades below the stability and sampling bound where the edge is sought (and the grid's
#: bandwidths lie when no bandwidth meets the margins: then log-spaced, :data:`N_ALPHA`).
ALPHA_DECADES = 2.5
N_ALPHA = 7
#: Bisection steps of the edge (a precision of ``ALPHA_DECADES / 2**EDGE_STEPS`` decades).
EDGE_STEPS = 10
#: Factor by which the edge steps down where it misses a margin between the ends of the range.
EDGE_BACKOFF = 0.97
#: First step of the pattern search (a factor on zeta, the fraction of the edge, Ka Kp and m).
STEP_FIRST = 1.25
#: Back-calculation gain of the coarse grid, ``Ka Kp`` (1 is the paper's Ka = 1/Kp, section 3.3).
KA_KP_GRID = (0.5, 1.0, 2.0, 4.0)
#: Tracking pole factors of the coarse grid for the feedforwards of eq 11 (``no_tau``, ``full``).
M_GRID = (0.5, 1.0, 2.0)
#: Bounds of the search: zeta, ``Ka Kp`` and m (alpha's: the stability and sampling bound of the search).
ZETA_RANGE = (0.3, 2.0)
KA_KP_RANGE = (0.1, 10.0)
M_RANGE = (0.25, 4.0)
#: Most rounds of the pattern search around the best point, and its smallest step (a factor).
REFINE_ROUNDS = 12
REFINE_STEP_MIN = 1.01
#: Most "partial" candidates the search simulates at the other inertia ratios at a time, those of
#: best bound first: enough for the engine's threads, few enough that the best of them raises the bar
#: for the rest.
COMPLETE_BATCH = 4
#: Largest number of best designs simulated again over the inertia range.
CHECK_MAX = 20


def J_ratios(J_range: tuple[float, float], n: int) -> tuple[float, ...]:
    """``n`` inertia ratios log-spaced over ``J_range``, both ends included (one for a point range)."""
    lo, hi = J_range
    if lo == hi:
        return (lo,)
    return tuple(float(r) for r in np.geomspace(lo, hi, n))


def runs_bound(scenario: Scenario, spec: Spec) -> int:
    """The most simulations :func:`~pmsm2dof.studies.autotune_search.autotune` can make for ``scenario`` and
    ``spec``: a bound on its work.

    The coarse grid, :data:`REFINE_ROUNDS` rounds of at most 81 neighbours, each at the 3 inertia
    ratios of the search, and at most :data:`CHECK_MAX` final checks at :data:`N_J_CHECK` ratios.
    """
    sc = scenario.speed_controller
    forms = list(itertools.product(spec.feedforwards or (sc.feedforward,), spec.anti_windups or (sc.anti_windup,)))
    grid = 0
    neighbours = 0
    for ff, aw in forms:
        n_m = len(M_GRID) if ff in ("no_tau", "full") else 1
        n_ka = len(KA_KP_GRID) if aw == "back_calculation" else 1
        grid += len(ZETA_GRID) * max(len(ALPHA_FRACTIONS), N_ALPHA) * n_m * n_ka
        neighbours = max(neighbours, 9 * (3 if n_m > 1 else 1) * (3 if n_ka > 1 else 1))
    n_search = len(J_ratios(spec.J_range, 3))
    return (grid + REFINE_ROUNDS * neighbours) * n_search + CHECK_MAX * len(J_ratios(spec.J_range, N_J_CHECK))
