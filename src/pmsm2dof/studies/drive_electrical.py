"""Electrical identification on a drive: current steps played by the drive, captured at the current period, fitted.

The firmware's routine (examples/firmware/identify_task.h) plays a plan of dq current steps in the
control interrupt, between runs, with a current controller of the library at the rotor's angle:

- at standstill, d-axis steps ``+I``, ``-I``, ``+I/2``, ``-I/2`` (``iq = 0``: no torque): ``id``
  moves (Ld) and is held (Rs, eq 1 at d/dt = 0: ``ud = Rs id``);
- then q-axis steps at speed: ``+I`` until the rotor reaches ``w_high``, ``-I`` until it falls to
  ``w_high / 2``, twice over, then ``-I`` until it stops: ``iq`` moves at speed (Lq) and the speed
  terms of eq 1 carry psi_f. The steps end at their speeds whatever the inertia (a step also ends
  after its longest time, three times the one the configured inertia needs).

:func:`plan_electrical` makes the plan for the drive as its own configuration describes it
(:func:`pmsm2dof.studies.drive_commission.drive_scenario`): ``I`` is :data:`CURRENT_SHARE` of the
current limit, ``w_high`` :data:`SPEED_SHARE` of the speed at which eq 1's steady voltage at ``I``
reaches ``PLAN_VOLTAGE_SHARE u_dc / sqrt(3)`` with the configured motor (0.9: the margin leaves
room for a motor whose flux is up to twice the configured one), the trips at :data:`TRIP_SHARE`
above the plan's current and speed.

One plan holds far more current periods than the drive's capture buffer (examples/firmware/capture.h:
16 kB, some 680 records of the six float32 signals). :func:`capture_electrical` plays it once per
buffer's window: the buffer armed with a rising trigger on the routine's time ``identify_now.t_s``
at the window's start, the plan started, the window read out after. The windows, each a segment of
the log (:data:`GAP_SAMPLES` left out between them: the fit's windows never join two plays), are
the log of :func:`pmsm2dof.studies.electrical.identify_electrical`, the fit of ``pmsm2dof identify
electrical``, with the drive's DC link (windows at the voltage limit left out) and its computation
delay (``commission_config.voltage_delay_samples``).
"""

import dataclasses
import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ..drive.link import Link
from ..drive.session import link_errors, read_variable
from ..errors import ConfigError, SimulationError, ToolError
from ..outputs import atomic_file
from ..sim.logs import read_log
from ..sim.plausibility import voltage_limited_speed_radps
from ..sim.scenario import Scenario
from .drive_commission import drive_scenario
from .electrical import Electrical, identify_electrical
from .identify import PLAN_VOLTAGE_SHARE

#: The plan's current amplitude I, of the current limit [-].
CURRENT_SHARE = 0.5
#: The plan's top speed, of the speed where the voltage at I reaches PLAN_VOLTAGE_SHARE u_dc / sqrt(3) [-].
SPEED_SHARE = 0.5
#: The trips of the routine above the plan's current (I) and top speed [-].
TRIP_SHARE = 1.5
#: A q-current step lasts at most this many times the time the configured inertia needs [-].
STEP_TIME_FACTOR = 3.0
#: Most steps of a plan (IDENTIFY_STEPS_MAX), longest step [s] (IDENTIFY_STEP_MAX_S).
STEPS_MAX = 16
STEP_MAX_S = 10.0
#: Most windows (plays of the plan): the drive's time is the plan's times this.
WINDOWS_MAX = 64
#: Wall-clock time allowed per second of the drive's time, on top of a fixed minute [s] (QEMU runs slower).
WALL_S_PER_DRIVE_S = 120.0
#: Periods left out at the start of each later window: the log's gap (pmsm2dof.sim.logs.GAP_FACTOR periods and
#: more) that makes each play of the plan a segment of its own, the fit's windows within one play.
GAP_SAMPLES = 4
#: States of the firmware's identification task (identify_status_t.state), its failure reasons.
STATES = ("idle", "running", "done", "failed", "tripped", "aborted")
REASONS = ("none", "the current exceeded i_trip_A", "the speed exceeded w_trip_radps")
#: The captured signals of identify_now -> the log's columns (pmsm2dof.sim.logs).
SIGNALS = {
    "identify_now.t_s": "time_s",
    "identify_now.w_m_radps": "speed_radps",
    "identify_now.id_A": "id_A",
    "identify_now.iq_A": "iq_A",
    "identify_now.ud_V": "ud_V",
    "identify_now.uq_V": "uq_V",
}
#: What the drive does when the link drops during the identification (examples/firmware/identify_task.h).
SAFE_STATE_IDENTIFICATION = (
    "the drive falls back to its safe state by itself: its link watchdog ends the identification's current steps, "
    "zero voltage and the power stage off"
)


@dataclasses.dataclass(frozen=True)
class Step:
    """One step of the plan: dq current references held until ``t_s`` or the speed ``w_end_radps``."""

    id_A: float
    iq_A: float
    t_s: float
    w_end_radps: float

    def to_json(self) -> dict[str, float]:
        return dataclasses.asdict(self)


@dataclasses.dataclass(frozen=True)
class ElectricalPlan:
    """The current steps of the identification and the routine's trips (identify_config_t)."""

    steps: tuple[Step, ...]
    i_A: float
    w_high_radps: float
    i_trip_A: float
    w_trip_radps: float
    Ts_s: float
    #: the plan's length with the configured inertia [s] (a heavier rotor takes longer)
    nominal_s: float

    def config(self) -> dict[str, Any]:
        """The plan as the firmware's identify_config fields."""
        return {
            "identify_config.n": len(self.steps),
            "identify_config.i_trip_A": self.i_trip_A,
            "identify_config.w_trip_radps": self.w_trip_radps,
            **{f"identify_config.{k}": [getattr(s, k) for s in self.steps] for k in ("id_A", "iq_A", "t_s")},
            "identify_config.w_end_radps": [s.w_end_radps for s in self.steps],
        }

    def to_json(self) -> dict[str, Any]:
        out = {k: v for k, v in dataclasses.asdict(self).items() if k != "steps"}
        out["steps"] = [s.to_json() for s in self.steps]
        return out


def plan_electrical(drive: Scenario, speed_max_rpm: float | None = None) -> ElectricalPlan:
    """The identification's current steps for a drive (module docstring) from its configuration.

    Parameters
    ----------
    drive : Scenario
        The drive as its configuration describes it (:func:`~pmsm2dof.studies.drive_commission.drive_scenario`).
    speed_max_rpm : float, optional
        The plan's top speed [rpm], > 0, at most the default (module docstring), which it lowers.

    Raises
    ------
    ConfigError
        A bad ``speed_max_rpm``, or a drive whose voltage leaves no speed at the plan's current.
    """
    motor, limits = drive.motor, drive.limits
    i_A = CURRENT_SHARE * limits.i_max_A
    u_plan_V = PLAN_VOLTAGE_SHARE * limits.u_dc_V / math.sqrt(3.0)
    w_limit = SPEED_SHARE * voltage_limited_speed_radps(u_plan_V, i_A, motor)
    if not w_limit > 0.0:
        raise ConfigError("limits.u_dc_V", limits.u_dc_V, f"> Rs i / ({PLAN_VOLTAGE_SHARE:g} / sqrt(3)) at {i_A:g} A")
    w_high = w_limit
    if speed_max_rpm is not None:
        if not (math.isfinite(speed_max_rpm) and 0.0 < speed_max_rpm <= w_limit * 30.0 / math.pi):
            raise ConfigError("speed_max_rpm", speed_max_rpm, f"(0, {w_limit * 30.0 / math.pi:.5g}] rpm")
        w_high = speed_max_rpm * math.pi / 30.0
    Ts_s = drive.current_loop.Ts_s
    # the steps at standstill: the current loop settles in some 5 tau_i, the flux in 5 L / Rs (eq 1)
    t_hold = max(20.0 * drive.current_loop.tau_i_s, 5.0 * max(motor.Ld_H, motor.Lq_H) / motor.Rs_ohm, 200 * Ts_s)
    steps = [Step(i, 0.0, t_hold, 0.0) for i in (i_A, -i_A, 0.5 * i_A, -0.5 * i_A)]
    # J dw/dt = 1.5 p psi_f iq (eq 2, no load): the time of a speed change at I with the configured inertia
    acc = 1.5 * motor.pole_pairs * motor.psi_f_Wb * i_A / drive.speed_controller.J_kgm2
    w_low = 0.5 * w_high

    def q_step(sign: float, w_end: float, dw: float) -> Step:
        return Step(0.0, sign * i_A, min(STEP_MAX_S, STEP_TIME_FACTOR * dw / acc), w_end)

    steps += [q_step(1.0, w_high, w_high)]
    for _ in range(2):
        steps += [q_step(-1.0, w_low, w_high - w_low), q_step(1.0, w_high, w_high - w_low)]
    steps += [q_step(-1.0, 0.0, w_high), Step(0.0, 0.0, t_hold, 0.0)]
    nominal = 5 * t_hold + (w_high + 4 * (w_high - w_low) + w_high) / acc
    return ElectricalPlan(
        steps=tuple(steps),
        i_A=i_A,
        w_high_radps=w_high,
        i_trip_A=TRIP_SHARE * i_A,
        w_trip_radps=TRIP_SHARE * w_high,
        Ts_s=Ts_s,
        nominal_s=nominal,
    )


def window_samples(link: Link) -> int:
    """Records of :data:`SIGNALS` the drive's capture buffer holds."""
    record = sum(link.scalar(name).size for name in SIGNALS)
    return int(link.variables["capture_buffer"].size // record)


def capture_electrical(
    link: Link,
    plan: ElectricalPlan,
    log: Path | str,
    *,
    progress: Callable[[int, float], None] | None = None,
) -> int:
    """Play ``plan`` on the drive once per window of its capture buffer, write the windows to ``log`` (CSV).

    Returns the number of rows (current periods captured). ``progress(window, t_s)`` is called as each
    window is read, with the plan's time it reached [s].

    Raises
    ------
    ConfigError
        The plan needs more than :data:`WINDOWS_MAX` windows.
    ToolError
        The drive has no identification routine or capture buffer, is busy, refused the plan, the link
        dropped (its watchdog then ends the routine: power off), or a play did not end in time.
    SimulationError
        A play did not end done (a trip of the routine, its watchdog).
    """
    if "identify_now" not in link.variables or "capture_buffer" not in link.variables:
        raise ToolError(
            f"the drive at {link.url} has no electrical identification or no capture buffer (its A2L file lacks "
            "identify_now or capture_buffer): a firmware of examples/firmware of this version has both"
        )
    W = window_samples(link)
    nominal = int(math.ceil(plan.nominal_s / plan.Ts_s / W))
    if nominal > WINDOWS_MAX:
        raise ConfigError(
            "plan", f"{plan.nominal_s:.4g} s", f"at most {WINDOWS_MAX} windows of {W * plan.Ts_s:.4g} s of the buffer"
        )
    # a heavier rotor than the configured one plays longer: windows until the plan ends, at most its steps' times
    longest_s = sum(s.t_s for s in plan.steps)
    windows = min(WINDOWS_MAX, int(math.ceil(longest_s / plan.Ts_s / W)))
    timeout = 60.0 + WALL_S_PER_DRIVE_S * longest_s
    names = list(SIGNALS)
    parts: list[pd.DataFrame] = []
    with link_errors(link, "the electrical identification", SAFE_STATE_IDENTIFICATION):
        if link.status()["state"] == "running":
            raise ToolError(f"the drive at {link.url} is running: wait for its end or stop it")
        link.write(plan.config())
        for j in range(windows):
            before = read_variable(link, "identify_now")

            play = int(before["starts"]) + 1

            def start(link: Link) -> None:
                link.write({"identify_command.command": 1})

            def before_the_window(link: Link, first: int = j * W + 1, play: int = play) -> None:
                # a play that ended before the window's first sample: a trip (raised), or done (the plan was
                # shorter than the last play's): its trigger will not come
                now = read_variable(link, "identify_now")
                if now["starts"] == play and STATES[now["state"]] != "running" and _ended(now)["sample"] < first:
                    raise _EndedBeforeWindow

            # the window of samples j W + 1 .. (j + 1) W: the trigger is t_s crossing from j W to j W + 1
            level = (j * W + 0.5) * plan.Ts_s
            try:
                cap = link.capture_buffered(
                    names, event="current", samples=W, trigger="rising", level=level,
                    trigger_signal="identify_now.t_s", armed=start, during=before_the_window, timeout_s=timeout,
                )  # fmt: skip
            except _EndedBeforeWindow:
                link.write({"capture_config.command": 2})
                break
            end = _wait_end(link, play, timeout)
            t = cap.signals["identify_now.t_s"].astype(np.float64)
            k = np.rint(t / plan.Ts_s)
            # the records of the plan (a plan shorter than the window ends inside it; the buffer holds idle periods)
            keep = np.arange(len(k)) < _first_repeat(k)
            # each play a segment of the log: a gap of GAP_SAMPLES periods before each later window
            keep[: GAP_SAMPLES if j > 0 else 0] = False
            frame = pd.DataFrame({col: cap.signals[name][keep].astype(np.float64) for name, col in SIGNALS.items()})
            frame["time_s"] = k[keep] * plan.Ts_s
            parts.append(frame)
            if progress is not None:
                progress(j + 1, min((j + 1) * W, int(end["sample"])) * plan.Ts_s)
            if end["sample"] <= (j + 1) * W:
                break
        else:
            raise SimulationError(
                f"the identification's current steps lasted beyond {windows} windows of the capture buffer "
                f"({windows * W * plan.Ts_s:.4g} s): a rotor far heavier than the drive's configuration"
            )
    data = pd.concat(parts, ignore_index=True)
    with atomic_file(log, "w") as f:
        data.to_csv(f, index=False)
    return len(data)


class _EndedBeforeWindow(Exception):
    """A play of the plan ended done before the window's first sample (it was shorter than the last one)."""


def _first_repeat(k: np.ndarray) -> int:
    """The index of the first record that does not follow its predecessor by one period (the plan ended)."""
    breaks = np.flatnonzero(np.diff(k) != 1)
    return int(breaks[0] + 1) if breaks.size else len(k)


def _wait_end(link: Link, start: int, timeout_s: float) -> dict[str, Any]:
    """Poll identify_now (which feeds the watchdog) until the play ``start`` ends; it must end done."""
    end = time.monotonic() + timeout_s
    while True:
        now = read_variable(link, "identify_now")
        if now["starts"] == start and STATES[now["state"]] != "running":
            break
        if time.monotonic() > end:
            raise ToolError(f"the identification's current steps did not end within {timeout_s:g} s of the wall clock")
        time.sleep(0.01)
    return _ended(now)


def _ended(now: dict[str, Any]) -> dict[str, Any]:
    """identify_now of a play that ended; SimulationError unless it ended done."""
    state = STATES[now["state"]]
    if state != "done":
        why = {
            "failed": REASONS[now["reason"]] if now["reason"] < len(REASONS) else f"reason {now['reason']}",
            "tripped": "its link watchdog",
            "aborted": "the master",
        }.get(state, state)
        raise SimulationError(
            f"the identification's current steps on the drive ended {state} ({why}) in step {now['step']} at "
            f"{now['t_s']:.4g} s; the power stage is off"
        )
    return now


def identify_on_drive(
    link: Link,
    log: Path | str,
    *,
    speed_max_rpm: float | None = None,
    progress: Callable[[int, float], None] | None = None,
) -> tuple[ElectricalPlan, Electrical, Scenario]:
    """Plan, play and capture the identification on the drive (module docstring), and fit eq 1 to the capture.

    Writes the capture to ``log`` (CSV). Returns the plan, the fit of
    :func:`pmsm2dof.studies.electrical.identify_electrical` and the drive's configuration (its pole pairs).

    Raises
    ------
    ConfigError, ToolError, SimulationError
        As :func:`plan_electrical` and :func:`capture_electrical`.
    IdentificationError
        A parameter the capture does not determine.
    """
    drive = drive_scenario(link)
    plan = plan_electrical(drive, speed_max_rpm)
    with link_errors(link, "reading the drive's computation delay"):
        delay = int(read_variable(link, "commission_config")["voltage_delay_samples"])
    capture_electrical(link, plan, log, progress=progress)
    fit = identify_electrical(
        read_log(log), drive.motor.pole_pairs, voltage_delay_samples=delay, u_dc_V=drive.limits.u_dc_V
    )
    return plan, fit, drive
