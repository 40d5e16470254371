"""The verdicts' rules and the helpers the claims share (:mod:`pmsm2dof.studies.claims`)."""

import dataclasses
import math
from collections.abc import Mapping
from typing import Any

import numpy as np
import numpy.typing as npt

from ...sim.metrics import at_current_limit
from ...sim.simulate import Result
from .. import paper as st
from .. import paper_runs as pr

#: Verdicts, best first.
VERDICTS = ("reproduced", "partly", "not reproduced")
#: "About x" of the paper: within this fraction of x.
ABOUT_RTOL = 0.25
#: Two responses are "the same" when they differ by less than this fraction of the load dip.
SAME_RTOL = 0.01
#: A response "is first order" when its rise time and bandwidth are within this fraction of eq 10's.
FIRST_ORDER_RTOL = 0.05
#: Overshoot [%] below which a step response counts as "without overshoot".
NO_OVERSHOOT_PCT = 1.0
#: Anti-windup "does not make it worse": its overshoot exceeds that without by at most this [percentage points].
AW_TOLERANCE_PP = 0.5
#: A load is "well" rejected when the speed dips by at most this fraction of the speed.
GOOD_DIP_FRACTION = 0.1
#: Values of m of the Fig. 7 claim and figure (the paper: alpha = 0.5, m from 0.2 to 2).
FIG7_M = (0.2, 0.5, 1.0, 1.5, 2.0)
#: End of the first window of simulation condition 1 (the second step) [s].
C1_SECOND_STEP_S = 5.0

SOURCES = ("design", "simulation", "design+simulation", "implementation")


@dataclasses.dataclass(frozen=True)
class Claim:
    """One claim of the paper and what the reproduction measured.

    Attributes
    ----------
    id : str
        ``C1``, ``C2``, ... in the order of the paper's sections.
    section : str
        Where the paper makes the claim.
    claim : str
        The claim, in the paper's words where possible.
    paper : str
        The paper's value.
    measured : str
        What the reproduction measured, in words with the numbers.
    values : dict
        The measured numbers (name -> float or list of floats).
    verdict : str
        One of :data:`VERDICTS`.
    reason : str
        Why the verdict, where the numbers differ or the reading needs a word.
    source : str
        One of :data:`SOURCES`: what the measured values come from.
    evidence : str
        The runs and figures used.
    on_drive : OnDrive or None
        The same claim checked on the runs played on a drive (``reproduce --link``), for the
        claims of the experiments; None otherwise.
    """

    id: str
    section: str
    claim: str
    paper: str
    measured: str
    values: dict[str, Any]
    verdict: str
    reason: str
    source: str
    evidence: str
    on_drive: "OnDrive | None" = None


@dataclasses.dataclass(frozen=True)
class OnDrive:
    """A claim checked on the runs played on a drive (:mod:`pmsm2dof.studies.paper_drive`).

    Attributes
    ----------
    measured : str
        What the drive's runs measured, in words with the numbers.
    values : dict
        The measured numbers, as :attr:`Claim.values`.
    verdict : str
        One of :data:`VERDICTS`, by the same rule as the simulated runs'.
    link : str
        Where the runs were played.
    speed_difference : float
        Largest difference of the drive's speed from the engine's over the claim's runs, as a
        fraction of the speed step.
    """

    measured: str
    values: dict[str, Any]
    verdict: str
    link: str
    speed_difference: float


# ---------------------------------------------------------------------------------------------
# measurements on the results
# ---------------------------------------------------------------------------------------------


def _value(figure: Mapping[str, Any]) -> Any:
    """The value of a figure of :mod:`pmsm2dof.sim.metrics`: a float, or None when it is missing."""
    return figure["value"]


def _overshoot(studies: st.Studies, run: str, index: int = 0) -> tuple[float, str]:
    """Overshoot [%] of reference step ``index`` of ``run``, and a note.

    When the speed approaches the new reference from one side without reaching it before the
    window ends, :mod:`pmsm2dof.sim.metrics` has no overshoot; it is then 0 (the note says so).
    """
    step = studies.step(run, index)
    value = _value(step["overshoot_pct"])
    if value is not None:
        return value, ""
    result = studies.results[run]
    t0, t1 = step["t_s"], step["window_end_s"]
    inside = (result.t_s >= t0) & (result.t_s <= t1)
    z = (result.speed_rpm[inside] - step["speed_at_step_rpm"]) / (step["to_rpm"] - step["speed_at_step_rpm"])
    peak = float(np.max(z))
    if peak < 1.0:
        return 0.0, f"no overshoot (the speed reaches {100 * peak:.1f} % of the step before {t1:g} s)"
    return 100.0 * (peak - 1.0), ""


def fmt(x: float | None, digits: int = 3, unit: str = "") -> str:
    """``x`` with ``digits`` significant digits and its unit, or ``n/a`` for None or a non-finite value."""
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "n/a"
    return f"{x:.{digits}g}{(' ' + unit) if unit else ''}"


def _limit_run(result: Result, t0: float) -> tuple[float, float]:
    """(delay, duration) [s] of the first unbroken stretch at the current limit after ``t0``.

    At the limit as :func:`pmsm2dof.sim.metrics.at_current_limit` says (the flag, or the command
    within 1 % of the limit), so that a flag that toggles while the command holds does not cut it.
    """
    t, limited = result.t_s, at_current_limit(result)
    after = np.nonzero(limited & (t >= t0))[0]
    if after.size == 0:
        return math.nan, 0.0
    k = after[0]
    ends = np.nonzero(~limited[k:])[0]
    end = t[k + ends[0]] if ends.size else t[-1]
    return float(t[k] - t0), float(end - t[k])


def _window(result: Result, t0: float, t1: float) -> npt.NDArray[np.bool_]:
    inside: npt.NDArray[np.bool_] = (result.t_s >= t0) & (result.t_s < t1)
    return inside


def _crossing(x: npt.ArrayLike, y: npt.ArrayLike, level: float) -> float | None:
    """First x where ``y`` crosses ``level`` (linear interpolation), or None."""
    xs, ys = np.asarray(x, float), np.asarray(y, float)
    for k in range(len(xs) - 1):
        a, b = ys[k] - level, ys[k + 1] - level
        if math.isfinite(a) and math.isfinite(b) and a * b <= 0.0 and a != b:
            return float(xs[k] + a / (a - b) * (xs[k + 1] - xs[k]))
    return None


def _verdict(ok: bool | np.bool_, partly: bool | np.bool_ = False) -> str:
    return VERDICTS[0] if ok else (VERDICTS[1] if partly else VERDICTS[2])


def _series(sweep: pr.Sweep, label: str, kind: str) -> pr.Series:
    return next(s for s in sweep.series if s.label == label and s.kind == kind)


def _along(studies: st.Studies, sweep: pr.Sweep, label: str, kind: str, figure: str) -> npt.NDArray[np.float64]:
    """``figure`` along the series ``label`` of ``kind`` (step or load) of ``sweep`` (NaN where missing)."""
    return studies.series_values(_series(sweep, label, kind), figure)


def _reference(sweep: pr.Sweep, label: str) -> pr.RunSpec:
    return next(r for lbl, r in sweep.references if lbl == label)


def _claim(**fields: Any) -> Claim:
    return Claim(id="", **fields)


def _over_text(value: float, note: str) -> str:
    return note if note else f"{value:.1f} %"
