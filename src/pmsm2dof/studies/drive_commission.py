"""Self-commissioning on a drive: the C routine of ``commission.h`` run by the drive's firmware, followed over XCP.

The firmware (examples/firmware/commission_task.h) runs the library's routine in its control
interrupt when the master asks for it, between runs: the same code as the engine's run of it
(:func:`pmsm2dof.sim.commission.commission`), now against the drive's own motor, with the power
stage's trip current and the link watchdog in force. :func:`commission_on_drive` writes the
routine's configuration, starts it, follows its steps by DAQ at the speed event (the signals of
the engine's commissioning log), and reads its estimates and checks when it ends.

The host knows only what the drive tells it: the routine's configuration is derived
(:func:`pmsm2dof.sim.commission.commissioning_config`) from the motor data the drive's
controllers hold (``link_speed_config``, ``link_current_config``: the datasheet's values the drive
was set up with) and the DC link it measures, as a commissioning engineer would from the motor's
rough data; what the routine finds is the motor's.
"""

import math
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from ..core.bindings import c_string, lib
from ..drive.link import Link
from ..drive.session import SAFE_STATE_COMMISSIONING, link_errors, read_variable
from ..errors import ConfigError, SimulationError, ToolError
from ..sim.commission import ESTIMATES, PHASES, REASONS, Commissioning, commissioning_config
from ..sim.scenario import Scenario

#: States of the firmware's commissioning task (commission_status_t.state).
STATES = ("idle", "running", "done", "failed", "tripped", "aborted")
#: The signals followed by DAQ at the speed event: the engine's commissioning log, and the sample count.
LOG_SIGNALS = ("phase", "id_A", "iq_A", "ud_V", "uq_V", "w_e_frame_radps", "w_e_radps", "theta_err_rad")
#: The routine's checks read at its end (as :attr:`pmsm2dof.sim.commission.Commissioning.checks`).
CHECKS = ("u_err_V", "rs_spread", "uq_ratio", "asymmetry", "coherence", "psi_spread", "slip", "L_probe_H")
#: commission_now.phase_start of a step not reached.
NOT_REACHED = 2**32 - 1
#: Wall-clock time allowed per second of the routine's nominal time, on top of a fixed minute [s] (QEMU is slower).
WALL_S_PER_DRIVE_S = 120.0
#: Longest routine the host follows, of the drive's time [s] (the engine's T_MAX_S is an hour; a drive's is minutes).
ROUTINE_MAX_S = 600.0


def drive_scenario(link: Link) -> Scenario:
    """The drive as its own configuration describes it: the motor data its controllers hold, its DC link.

    The controllers' ``[motor]`` (pole pairs, Rs, Ld, Lq, psi_f, the inertia J the speed controller
    is designed for), ``limits.i_max_A``, the loop periods and the speed controller's bandwidth are
    read from ``link_speed_config`` and ``link_current_config``, ``limits.u_dc_V`` from the DC link
    the drive measures (``commission_now.u_dc_V``). These are the data the drive was set up with,
    not the motor's true values.

    Raises
    ------
    ConfigError
        The drive's firmware has no commissioning task (its A2L lacks ``commission_now``), or its
        configuration is not a valid scenario (named by its key).
    ToolError
        The link dropped.
    """
    with link_errors(link, "reading the drive's configuration"):
        sc = read_variable(link, "link_speed_config")
        cc = read_variable(link, "link_current_config")
        now = read_variable(link, "commission_now")
    u_dc_V = float(now["u_dc_V"])
    if not (math.isfinite(u_dc_V) and u_dc_V > 0.0):
        raise ConfigError("commission_now.u_dc_V", u_dc_V, "> 0 V: the drive measures no DC link")
    Ts_speed_s = float(np.float32(sc["Ts_s"]))
    tree = {
        "name": f"the drive at {link.url}",
        "description": "the motor data and limits the drive's controllers hold, the DC link it measures",
        "motor": {
            "pole_pairs": int(sc["pole_pairs"]),
            **{k: _f(cc[k]) for k in ("Rs_ohm", "Ld_H", "Lq_H", "psi_f_Wb")},
            "J_kgm2": _f(sc["J_kgm2"]),
        },
        "limits": {"i_max_A": _f(sc["i_max_A"]), "u_dc_V": _f(u_dc_V)},
        "current_loop": {"model": "dq_pi", "tau_i_s": _f(cc["tau_i_s"]), "Ts_s": _f(cc["Ts_s"])},
        "speed_controller": {
            "alpha_radps": _f(sc["alpha_radps"]),
            "zeta": _f(sc["zeta"]),
            "Ts_s": _f(Ts_speed_s),
            "J_kgm2": _f(sc["J_kgm2"]),
        },
        "simulation": {"t_end_s": 10.0 * Ts_speed_s},
        "reference": [{"t_s": 0.0, "speed_rpm": 0.0}],
    }
    return Scenario.from_dict(tree)


def _f(x: Any) -> float:
    """A float32 of the drive as the shortest decimal that is it (0.0005, not 0.0005000000237487257)."""
    return float(str(np.float32(x)))


def nominal_time_s(config: dict[str, float | int]) -> float:
    """The routine's nominal length [s]: its steps' times (the amplitude search of PROBE and LD, LQ are short)."""
    c = config
    return float(
        c["t_align_s"] + 2 * c["t_level_s"] + 2 * c["t_inductance_s"] + 2 * c["t_ramp_s"] + c["t_spin_s"] + 0.1
    )


def commission_on_drive(
    link: Link, *, progress: Callable[[str, float], None] | None = None, wall_timeout_s: float | None = None
) -> Commissioning:
    """Run the commissioning routine on the drive and return its outcome as the engine's run would.

    Parameters
    ----------
    link : Link
        An open link to a drive whose firmware has the commissioning task (examples/firmware).
    progress : callable, optional
        ``progress(step, t_s)``: called when the routine enters a step (its name, :data:`PHASES`),
        with the drive's time since the start [s].
    wall_timeout_s : float, optional
        Longest wall-clock wait for the routine's end [s] (default: a minute plus
        :data:`WALL_S_PER_DRIVE_S` per second of its nominal length).

    Returns
    -------
    Commissioning
        ``estimates`` and ``checks`` the drive's routine found, ``truth`` NaN (a drive's motor has no
        known truth), ``config`` the routine's configuration, ``log`` the followed signals at the
        speed event, ``phase_time_s`` from the sample each step started at.

    Raises
    ------
    ConfigError
        The drive has no commissioning task, its configuration gives no valid routine (naming the
        field), or the routine would be longer than :data:`ROUTINE_MAX_S`.
    ToolError
        The drive is running, refused the start, the link dropped (the drive's watchdog then ends the
        routine: power off), or the routine did not end in time.
    SimulationError
        The routine ended by the watchdog or the master, or the DAQ lost samples.
    """
    scenario = drive_scenario(link)
    with link_errors(link, "reading the commissioning's configuration"):
        drive_cfg = read_variable(link, "commission_config")
        status = link.status()
        before = read_variable(link, "commission_now")
    config = commissioning_config(scenario)
    # the board knows its PWM timing: its computation delay stays the drive's
    config["voltage_delay_samples"] = int(drive_cfg["voltage_delay_samples"])
    config = {k: (v if isinstance(v, int) else _f(v)) for k, v in config.items()}
    t_nominal = nominal_time_s(config)
    if t_nominal > ROUTINE_MAX_S:
        raise ConfigError("commissioning", f"{t_nominal:.4g} s", f"at most {ROUTINE_MAX_S:g} s of the drive's time")
    if status["state"] == "running":
        raise ToolError(f"the drive at {link.url} is running (sample {status['sample']}): wait for its end or stop it")
    if STATES[before["state"]] == "running":
        raise ToolError(f"the drive at {link.url} is commissioning already (sample {before['sample']})")
    Ts_s = float(config["Ts_s"])
    timeout = wall_timeout_s if wall_timeout_s is not None else 60.0 + WALL_S_PER_DRIVE_S * t_nominal
    names = ["commission_now.starts", "commission_now.sample", *(f"commission_now.{s}" for s in LOG_SIGNALS)]
    followed: dict[str, Any] = {}

    def ended(link: Link) -> bool:
        if not followed:
            link.write({f"commission_config.{k}": v for k, v in config.items()})
            link.write({"commission_command.command": 1})
            followed.update(started=time.monotonic(), reported=0)
        now = read_variable(link, "commission_now")
        followed["now"] = now
        if now["starts"] != before["starts"] + 1:
            return False
        # every step started since the last poll, in order, at the sample it started
        started = sorted((k, p) for p, k in enumerate(now["phase_start"]) if k != NOT_REACHED)
        for k, p in started[followed["reported"] :]:
            if progress is not None:
                progress(PHASES[p], k * Ts_s)
        followed["reported"] = len(started)
        if time.monotonic() - followed["started"] > timeout:
            raise ToolError(f"the commissioning did not end within {timeout:g} s of the wall clock (state running)")
        return STATES[now["state"]] != "running"

    with link_errors(link, "the commissioning", SAFE_STATE_COMMISSIONING):
        cap = link.capture(names, until=ended)
        end = read_variable(link, "commission_now")
    state = STATES[end["state"]]
    if state in ("tripped", "aborted"):
        raise SimulationError(
            f"the commissioning on the drive was ended by {'its link watchdog' if state == 'tripped' else 'the master'}"
            f" in {PHASES[end['phase']]} at {end['sample'] * Ts_s:.4g} s; the power stage is off"
        )
    if cap.dtos_lost:
        raise SimulationError(f"the DAQ lost {cap.dtos_lost} samples of the commissioning")
    return _outcome(link, end, cap.signals, config, before["starts"] + 1)


def _outcome(
    link: Link, end: dict[str, Any], signals: dict[str, Any], config: dict[str, float | int], start: int
) -> Commissioning:
    """The routine's end state and its followed signals as a :class:`Commissioning`."""
    Ts_s = float(config["Ts_s"])
    mine = (signals["commission_now.starts"] == start) & (signals["commission_now.sample"] >= 1)
    k, first = np.unique(signals["commission_now.sample"][mine], return_index=True)
    log = {"t_s": (k - 1).astype(np.float64) * Ts_s}
    for s in LOG_SIGNALS:
        log[s] = signals[f"commission_now.{s}"][mine][first].astype(np.float64)
    done = PHASES[end["phase"]] == "done"
    # the time of each step, from the sample it started to the start of the next one reached (as the engine's)
    starts = [int(k) for k in end["phase_start"]]
    phase_time_s: dict[str, float] = {}
    for i in range(lib.P2D_PHASE_DONE):
        if starts[i] == NOT_REACHED:
            continue
        later = [k for k in starts[i + 1 : lib.P2D_PHASE_DONE] if k != NOT_REACHED]
        phase_time_s[PHASES[i]] = ((min(later) if later else int(end["sample"])) - starts[i]) * Ts_s
    estimates = {k: float(end[k]) for k in ESTIMATES}
    if not done:
        finished = {"Rs_ohm": lib.P2D_PHASE_LD, "Ld_H": lib.P2D_PHASE_RAMP_UP, "Lq_H": lib.P2D_PHASE_RAMP_UP}
        for key in ESTIMATES:
            if end["failed_phase"] < finished.get(key, lib.P2D_PHASE_DONE):
                estimates[key] = math.nan
    return Commissioning(
        scenario=f"the drive at {link.url}",
        phase=PHASES[end["phase"]],
        failed_phase=None if done else PHASES[end["failed_phase"]],
        reason=None if done else REASONS[end["reason"]],
        reason_text=c_string(lib.p2d_commission_reason_text(end["reason"])),
        estimates=estimates,
        truth={k: math.nan for k in ESTIMATES},
        phase_time_s=phase_time_s,
        config=config,
        checks={k: float(end[k]) for k in CHECKS},
        log=log,
    )
