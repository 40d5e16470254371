"""Identification on a drive: the identification plan played on the drive, its capture, the fit of ``identify``.

:func:`plan_on_drive` builds the speed steps of :func:`pmsm2dof.studies.identify.plan_experiment`
for the drive as its own configuration describes it
(:func:`pmsm2dof.studies.drive_commission.drive_scenario`: the current limit, the DC link, the
inertia its speed controller is designed for): the largest speed is where the voltage of eq 1 at
the current limit reaches :data:`pmsm2dof.studies.identify.PLAN_VOLTAGE_SHARE` of ``u_dc /
sqrt(3)`` unless a lower one is asked for. :func:`capture_plan` plays it as a run of the drive
(``link_reference``, the run control of examples/firmware/link.h) and captures by DAQ at the speed
event what any drive measures (``foc_now``: the speed reading and the dq currents), one row per
speed sample; the result is a drive log (CSV) for
:func:`pmsm2dof.studies.identify.identify_mechanics`, which the command reads back as
``pmsm2dof identify mechanics`` would.
"""

import math
import time
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ..drive.link import Link
from ..drive.session import link_errors
from ..errors import ConfigError, SimulationError, ToolError
from ..outputs import atomic_file
from ..sim.plausibility import voltage_limited_speed_radps
from ..sim.scenario import Scenario
from .drive_commission import drive_scenario
from .identify import PLAN_VOLTAGE_SHARE, plan_experiment

#: The capture's signals (foc_now of examples/firmware/foc.h) -> the drive log's columns (pmsm2dof.sim.logs): what
#: the fit needs and no more (each DAQ entry costs the control interrupt time, and the period that starts a run
#: is the longest: on the Cortex-M4F at 20 kHz, two more entries overran it).
SIGNALS = {"foc_now.w_meas_radps": "speed_radps", "foc_now.id_A": "id_A", "foc_now.iq_A": "iq_A"}
#: Longest plan played over the link, of the drive's time [s].
PLAN_MAX_S = 120.0
#: Wall-clock time allowed per second of the plan, on top of a fixed minute [s] (QEMU runs slower).
WALL_S_PER_DRIVE_S = 120.0


def plan_on_drive(link: Link, speed_max_rpm: float | None = None) -> Scenario:
    """The identification plan for the drive, from its own configuration (module docstring), ending at standstill.

    The steps of :func:`pmsm2dof.studies.identify.plan_experiment`, then a step to zero held as
    long as the others (twice the time of the change at the current limit, plus ``8 / alpha``).

    Parameters
    ----------
    link : Link
        An open link to the drive.
    speed_max_rpm : float, optional
        Largest speed of the plan [rpm], > 0; default: the speed where the voltage at the current
        limit reaches ``PLAN_VOLTAGE_SHARE u_dc / sqrt(3)`` (a higher one is lowered to it, with a
        :class:`pmsm2dof.studies.identify.PlanWarning`).

    Raises
    ------
    ConfigError
        A bad ``speed_max_rpm``, or a plan longer than :data:`PLAN_MAX_S`.
    """
    drive = drive_scenario(link)
    if speed_max_rpm is None:
        u_plan_V = PLAN_VOLTAGE_SHARE * drive.limits.u_dc_V / math.sqrt(3.0)
        speed_max_rpm = voltage_limited_speed_radps(u_plan_V, drive.limits.i_max_A, drive.motor) * 30 / math.pi
    plan = plan_experiment(drive, speed_max_rpm)
    # the run ends at standstill: a last step to zero held as the plan holds each step (the drive's power stage goes
    # off at the run's end, and the motor is left at rest for what comes next, a commissioning say)
    last = plan.reference[-1]
    T_max_Nm = 1.5 * plan.motor.pole_pairs * plan.motor.psi_f_Wb * plan.limits.i_max_A
    t_acc = plan.speed_controller.J_kgm2 * abs(last.speed_rpm) * math.pi / 30.0 / T_max_Nm
    t_stop = plan.simulation.t_end_s
    hold = 2.0 * t_acc + 8.0 / plan.speed_controller.alpha_radps
    plan = plan.with_overrides(
        {
            f"reference.{len(plan.reference)}": {"t_s": t_stop, "speed_rpm": 0.0},
            "simulation.t_end_s": round(t_stop + hold, 6),
        }
    )
    t_end = plan.simulation.t_end_s
    if t_end > PLAN_MAX_S:
        raise ConfigError("plan", f"{t_end:.4g} s", f"at most {PLAN_MAX_S:g} s of the drive's time")
    return plan


def capture_plan(link: Link, plan: Scenario, log: Path | str) -> int:
    """Play ``plan``'s reference on the drive, capture the signals of :data:`SIGNALS`, write them to ``log`` (CSV).

    Returns the number of rows (one per speed sample of the run, from its start).

    Raises
    ------
    ToolError
        The drive is running or refused the start, the link dropped (the drive's watchdog then
        ramps the speed to zero and switches the power stage off), or the run did not end in time.
    SimulationError
        The run did not end as done (tripped, stopped), or the DAQ lost samples.
    """
    Ts_speed_s = plan.speed_controller.Ts_s
    t_end = plan.simulation.t_end_s
    samples = int(math.ceil(t_end / Ts_speed_s))
    reference = [(e.t_s, e.speed_rpm * math.pi / 30.0, e.ramp_s) for e in plan.reference]
    timeout = 60.0 + WALL_S_PER_DRIVE_S * t_end
    names = ["link_status_now.runs", "link_status_now.sample", *SIGNALS]
    state: dict[str, Any] = {}
    with link_errors(link, "the identification run"):
        st = link.status()
        if st["state"] == "running":
            raise ToolError(f"the drive at {link.url} is running (sample {st['sample']}): wait for its end or stop it")
        link.set_schedules(reference)
        runs = int(st["runs"])

        def ended(link: Link) -> bool:
            if not state:
                link.start(samples)
                state["started"] = time.monotonic()
            now = link.status()
            state.update(now)
            if time.monotonic() - state["started"] > timeout:
                raise ToolError(f"the identification run did not end within {timeout:g} s of the wall clock")
            return bool(now["state"] != "running" and now["runs"] == runs + 1)

        cap = link.capture(names, until=ended)
    if state.get("state") != "done":
        raise SimulationError(
            f"the identification run ended {state.get('state')}, not done (trip at sample {state.get('trip_sample')})"
        )
    if cap.dtos_lost:
        raise SimulationError(f"the DAQ lost {cap.dtos_lost} samples of the identification run")
    mine = cap.signals["link_status_now.runs"] == runs + 1
    k, first = np.unique(cap.signals["link_status_now.sample"][mine], return_index=True)
    # the event of speed sample k carries the counter k (it steps after the event) and foc_now of that sample;
    # at k = samples the run is done and the control no longer runs
    keep = k < samples
    if int(keep.sum()) != samples:
        raise SimulationError(f"the capture holds {int(keep.sum())} of the run's {samples} samples")
    columns = {"time_s": k[keep].astype(np.float64) * Ts_speed_s}
    for name, column in SIGNALS.items():
        columns[column] = cap.signals[name][mine][first][keep].astype(np.float64)
    with atomic_file(log, "w") as f:
        pd.DataFrame(columns).to_csv(f, index=False)
    return samples
