"""A scenario on the drive and in the engine: the run played over the link, captured from the firmware's own signals.

A run captures what any drive with the firmware's variables measures (:data:`RUN_SIGNALS`: the
speed reading, the references, the dq currents, the torque command, the speed integrator and the
limit flags of ``foc_now``, examples/firmware/foc.h), at every speed sample: streamed by DAQ at
the speed event when the link carries it with room to spare, else recorded in the drive's capture
buffer (examples/firmware/capture.h) from the run's start and read out after
(:func:`plan_run`). The figures of a run are those of its measured speed, as a drive knows it;
the virtual board's trace of the plant's true state (``vd_trace``) is not needed.

Before a run the drive's controllers' configuration is read over the link and held against the
scenario's, field by field in float32: a drive that runs another design (a ``drive set`` since its
build) would not be the engine's run.
"""

import dataclasses
import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pandas as pd

from ..core import LOG_COLUMNS
from ..drive.link import Link
from ..drive.session import (
    CAPTURE_WAYS,
    CONTROLLERS,
    DAQ_OVERHEAD_BYTES,
    DAQ_SHARE,
    LINK_BYTES_PER_S,
    link_errors,
    link_kind,
)
from ..errors import ConfigError, SimulationError, ToolError
from ..outputs import atomic_file
from ..sim.metrics import compute_metrics
from ..sim.scenario import Scenario
from ..sim.simulate import RPM_PER_RADPS, RPM_SIGNALS, Result, Simulation, log_signals
from .autotune import CONSTRAINTS, MARGIN_FIGURES, Spec, step_figures
from .firmware import compare, serve_scenario

#: Longest run played over the link, of the drive's time [s] (the virtual board's schedules and the host's memory).
RUN_MAX_S = 600.0
#: Longest serve of a drive with a set duration [s] (a day; without one it serves until interrupted).
SERVE_MAX_S = 86400.0
#: Wall-clock time allowed per second of the drive's time, on top of a fixed minute [s] (QEMU runs slower).
WALL_S_PER_DRIVE_S = 60.0
#: The constraints of autotune's specification that a trace shows (the margins are the analytic loop's).
TRACE_CONSTRAINTS = tuple(name for name, (figure, _, _) in CONSTRAINTS.items() if figure not in MARGIN_FIGURES)
#: The firmware's signals a run captures at every speed sample (foc_now, examples/firmware/foc.h) -> the engine's log
#: column each fills: what the figures of merit (:func:`pmsm2dof.sim.metrics.compute_metrics`) and the comparison with
#: the engine need, and no more (each costs bytes of the link or of the capture buffer, and DAQ entries cost time in
#: the control interrupt). The measured speed fills the speed columns: a drive knows no other.
RUN_SIGNALS = {
    "foc_now.w_ref_radps": "w_ref_radps",
    "foc_now.w_meas_radps": "w_m_radps",
    "foc_now.id_ref_A": "id_ref_A",
    "foc_now.iq_ref_A": "iq_ref_A",
    "foc_now.id_A": "id_A",
    "foc_now.iq_A": "iq_A",
    "foc_now.T_ref_Nm": "torque_ref_Nm",
    "foc_now.x_i_Nm": "x_i_Nm",
    "foc_now.saturated": "saturated",
    "foc_now.voltage_limited": "voltage_limited",
}
#: The run's counters a DAQ capture adds to tell its samples (a buffered capture starts at the run's first sample).
RUN_COUNTERS = ("link_status_now.runs", "link_status_now.sample")
#: Columns of the engine's log a drive does not measure: NaN in a measured run (the flag J_valid: False).
NOT_MEASURED = (
    "ud_V", "uq_V", "torque_unsat_Nm", "load_Nm", "u_dc_V", "J_est_kgm2", "J_valid", "T_load_est_Nm",
    "J_gains_kgm2", "w_load_radps", "shaft_torque_Nm",
)  # fmt: skip


@dataclasses.dataclass(frozen=True)
class RunPlan:
    """How a run of the drive is captured (:func:`plan_run`).

    Attributes
    ----------
    samples : int
        Speed samples of the run.
    way : str
        ``"daq"``: streamed at the speed event; ``"buffer"``: recorded in the drive's capture buffer.
    record_bytes : int
        Bytes of the signals of one sample.
    need_bytes_per_s : float
        What DAQ would stream: (record + counters + :data:`~pmsm2dof.drive.session.DAQ_OVERHEAD_BYTES`) a sample,
        at the speed rate [bytes/s].
    link_bytes_per_s : float
        What the link streams [bytes/s].
    buffer_samples : int
        Samples of these signals the drive's capture buffer holds (0: it has none).
    why : str
        The choice, in a sentence.
    """

    samples: int
    way: str
    record_bytes: int
    need_bytes_per_s: float
    link_bytes_per_s: float
    buffer_samples: int
    why: str


def plan_run(link: Link, samples: int, *, way: str = "auto", link_bytes_per_s: float | None = None) -> RunPlan:
    """Choose how a run of ``samples`` speed samples is captured, before anything runs.

    DAQ at the speed event when its payload takes at most
    :data:`~pmsm2dof.drive.session.DAQ_SHARE` of what the link streams (``link_bytes_per_s``, else
    :data:`~pmsm2dof.drive.session.LINK_BYTES_PER_S` of its kind, as ``drive capture`` chooses):
    the run may be as long as the host keeps; else the drive's capture buffer, which must hold every
    sample of the run (a UART at 115200 baud streams some 11.5 kB/s, the :data:`RUN_SIGNALS` at a
    2 kHz speed loop need about 100 kB/s). ``way`` forces one.

    Raises
    ------
    ConfigError
        The drive lacks a signal of :data:`RUN_SIGNALS` (its A2L is not the firmware's), a bad ``way``
        or ``link_bytes_per_s``, or a run that neither way can capture (naming ``simulation.t_end_s``).
    """
    if way not in CAPTURE_WAYS:
        raise ConfigError("way", way, " or ".join(CAPTURE_WAYS))
    if link_bytes_per_s is not None and not (math.isfinite(link_bytes_per_s) and 1.0 <= link_bytes_per_s <= 1e10):
        raise ConfigError("link_bytes_per_s", link_bytes_per_s, "[1, 1e10] bytes/s")
    missing = [n for n in (*RUN_SIGNALS, *RUN_COUNTERS) if n not in link.scalars]
    if missing:
        raise ConfigError(
            "a2l", ", ".join(missing), "an A2L file of the firmware's build (it lists foc_now, link_status_now)"
        )
    Ts_speed_s = float(link.read("link_speed_config.Ts_s"))
    record = sum(link.scalars[n].size for n in RUN_SIGNALS)
    counters = sum(link.scalars[n].size for n in RUN_COUNTERS)
    need = (record + counters + DAQ_OVERHEAD_BYTES) / Ts_speed_s
    rate = link_bytes_per_s if link_bytes_per_s is not None else LINK_BYTES_PER_S[link_kind(link.url)]
    classic_can = link.url.startswith("can://") and "&fd=0" in link.url
    buffer_samples = link.variables["capture_buffer"].size // record if "capture_buffer" in link.variables else 0
    streams = need <= DAQ_SHARE * rate and not classic_can
    chosen = way if way != "auto" else "daq" if streams else "buffer"
    if chosen == "daq" and classic_can:
        raise ConfigError("way", way, "buffer or auto on classic CAN (fd=0): a DAQ packet of 8 bytes holds no signal")
    if chosen == "daq":
        why = (
            f"streamed by DAQ at the speed event: {need:.4g} bytes/s, the link {rate:.4g}"
            if streams
            else f"streamed by DAQ as asked ({need:.4g} bytes/s, the link {rate:.4g}: the drive may lose samples)"
        )
    else:
        if samples > buffer_samples:
            raise ConfigError(
                "simulation.t_end_s",
                f"{(samples - 1) * Ts_speed_s:g} s",
                f"at most {(buffer_samples - 1) * Ts_speed_s:g} s: the drive's capture buffer holds {buffer_samples} "
                f"samples of the run's {record}-byte records, and DAQ would need {need:.4g} bytes/s of a link that "
                f"streams {rate:.4g} (a faster link, or a shorter run)",
            )
        why = (
            f"recorded in the drive's capture buffer ({samples} of its {buffer_samples} samples) and read after: DAQ "
            f"would need {need:.4g} bytes/s, the link streams {rate:.4g}"
            if way == "auto"
            else f"recorded in the drive's capture buffer as asked ({samples} of its {buffer_samples} samples)"
        )
    return RunPlan(samples, chosen, record, need, rate, buffer_samples, why)


def capture_run(
    link: Link,
    scenario: Scenario,
    plan: RunPlan,
    *,
    timeout_s: float,
    during: Callable[[Link, dict[str, Any]], None] | None = None,
) -> Result:
    """Play ``scenario``'s reference on the drive for ``plan.samples`` speed samples; the measured run.

    The reference goes to ``link_reference``; the load schedule to the virtual board's ``vd_load``
    where the drive has one (on a bench the load is what the bench applies). The run starts from
    the drive's state (examples/firmware/link.h) and is captured as ``plan`` says; ``during(link,
    status)`` is called at the polls of the running drive (DAQ: with its status; buffer: with the
    status read then). The result is :func:`measured_result` of the samples 0 .. samples - 1.

    Raises
    ------
    ConfigError
        A schedule longer than the drive holds.
    ToolError
        The drive is running, or the run did not end within ``timeout_s`` of the wall clock.
    SimulationError
        The run did not end as done (stopped, tripped), or a sample is missing.
    """
    n = plan.samples
    reference = [(e.t_s, e.speed_rpm * (1.0 / RPM_PER_RADPS), e.ramp_s) for e in scenario.reference]
    load = [(e.t_s, e.torque_Nm, e.ramp_s) for e in scenario.load] if "vd_load" in link.variables else None
    before = link.status()
    if before["state"] == "running":
        raise ToolError(f"the drive at {link.url} is running (sample {before['sample']}): wait for its end or stop it")
    link.set_schedules(reference, load)
    runs = int(before["runs"])
    started = time.monotonic()

    def late() -> None:
        if time.monotonic() - started > timeout_s:
            raise ToolError(f"the run of {n} samples did not end within {timeout_s:g} s of the wall clock")

    if plan.way == "daq":
        state: dict[str, Any] = {}

        def ended(link: Link) -> bool:
            if not state:
                link.start(n)
            st = link.status()
            state.update(st)
            if during is not None and st["state"] == "running":
                during(link, st)
            late()
            return bool(st["state"] != "running" and st["runs"] == runs + 1)

        cap = link.capture([*RUN_COUNTERS, *RUN_SIGNALS], until=ended)
        if cap.dtos_lost:
            raise SimulationError(f"the DAQ lost {cap.dtos_lost} samples of the run")
        mine = cap.signals["link_status_now.runs"] == runs + 1
        k, first = np.unique(cap.signals["link_status_now.sample"][mine], return_index=True)
        # the event of speed sample k carries the counter k (it steps after the event) and foc_now of that sample;
        # at k = samples the run is done and the control no longer runs
        keep = k < n
        if int(keep.sum()) != n:
            raise SimulationError(f"the capture holds {int(keep.sum())} of the run's {n} samples")
        signals = {name: cap.signals[name][mine][first][keep] for name in RUN_SIGNALS}
        status = dict(state)
    else:

        def polled(link: Link) -> None:
            if during is not None:
                st = link.status()
                if st["state"] == "running":
                    during(link, st)
            late()

        # the trigger is the run's first control interrupt: record j is foc_now of the run's speed sample j
        cap = link.capture_buffered(
            list(RUN_SIGNALS), event="speed", samples=n, trigger="run", armed=lambda link: link.start(n),
            timeout_s=timeout_s, during=polled,
        )  # fmt: skip
        status = link.wait(
            ("done", "tripped", "stopped", "idle"), timeout_s=max(1.0, timeout_s - (time.monotonic() - started))
        )
        if status["runs"] != runs + 1:
            raise SimulationError(f"the drive's capture ended but no run started (status {status})")
        signals = dict(cap.signals)
    if status.get("state") != "done":
        raise SimulationError(f"the run over the link ended {status.get('state')}, not done (status {status})")
    return measured_result(
        scenario, {column: np.asarray(signals[name], dtype=np.float64) for name, column in RUN_SIGNALS.items()}
    )


def measured_result(scenario: Scenario, columns: dict[str, npt.NDArray[np.float64]]) -> Result:
    """A run the drive measured as a trace in the engine's log format: what the drive measures, and NaN.

    ``columns``: the engine's log columns of :data:`RUN_SIGNALS` at the run's speed samples 0, 1, ...
    (t = k Ts_speed, counted as the engine counts it). The speed columns hold the drive's speed
    reading (``w_meas_radps`` too), the electromagnetic torque is 1.5 p (psi_f iq + (Ld - Lq) id iq)
    of the measured currents with the scenario's motor data, and the columns of :data:`NOT_MEASURED`
    are NaN (``J_valid`` False).

    Raises
    ------
    SimulationError
        A measured value is not finite.
    """
    n = len(columns["w_m_radps"])
    m = scenario.motor
    log = {c: np.zeros(n) for c in LOG_COLUMNS}
    log.update(columns)
    log["t_s"] = sample_times(scenario, n)
    log["w_meas_radps"] = columns["w_m_radps"]
    id_A, iq_A = columns["id_A"], columns["iq_A"]
    log["torque_Nm"] = 1.5 * m.pole_pairs * (m.psi_f_Wb * iq_A + (m.Ld_H - m.Lq_H) * id_A * iq_A)
    signals = log_signals(np.array([log[c] for c in LOG_COLUMNS]))
    for c in NOT_MEASURED:
        name = RPM_SIGNALS.get(c, c)
        signals[name] = np.zeros(n, dtype=bool) if c == "J_valid" else np.full(n, np.nan)
    return Result(scenario=scenario, wall_time_s=0.0, **signals)


def save_run(result: Result, path: Path | str) -> None:
    """Write a measured run (:func:`measured_result`) as CSV: the engine's trace columns the drive measures.

    The columns of :data:`NOT_MEASURED` are left out, so that the file reads back as a drive log
    (:func:`pmsm2dof.sim.logs.read_log`) whose missing signals are missing, not NaN. Written whole
    or not at all.
    """
    dropped = {RPM_SIGNALS.get(c, c) for c in NOT_MEASURED}
    columns = {name: getattr(result, name) for name in Result.signals if name not in dropped}
    columns["saturated"] = columns["saturated"].astype(np.int8)
    with atomic_file(path, "w") as f:
        pd.DataFrame(columns).to_csv(f, index=False)


def sample_times(scenario: Scenario, n: int) -> npt.NDArray[np.float64]:
    """The times of the speed samples 0 .. n - 1 [s], as the engine and the virtual board count them (current
    periods)."""
    per_speed = round(scenario.speed_controller.Ts_s / scenario.current_loop.Ts_s)
    return (np.arange(n, dtype=np.float64) * per_speed) * scenario.current_loop.Ts_s


def as_measured(result: Result) -> Result:
    """The engine's run as the drive measures it: its speed columns are the speed reading (``speed_meas_rpm``)."""
    return dataclasses.replace(
        result, speed_rpm=result.speed_meas_rpm, w_m_radps=result.speed_meas_rpm * (1.0 / RPM_PER_RADPS)
    )


@dataclasses.dataclass(frozen=True, eq=False)
class DriveRun:
    """A scenario played on the drive and simulated by the engine over the same samples.

    Attributes
    ----------
    scenario : Scenario
    drive : Result
        The drive's measured run (:func:`measured_result`): its speed is the drive's speed reading.
    engine : Result
        The engine's simulation of the scenario (its speed the plant's, ``speed_meas_rpm`` the reading).
    url : str
        The link the run was played over.
    plan : RunPlan
        How the run was captured.
    """

    scenario: Scenario
    drive: Result
    engine: Result
    url: str
    plan: RunPlan

    def comparison(self) -> dict[str, Any]:
        """:func:`pmsm2dof.studies.firmware.compare` of the drive's run with the engine's as measured
        (:func:`as_measured`): reading against reading."""
        return compare(self.drive, as_measured(self.engine))


def judge(trace: Result, limits: dict[str, float]) -> dict[str, Any]:
    """Hold a run's trace against a specification: autotune's constraints (:data:`TRACE_CONSTRAINTS`) on its figures.

    ``limits`` maps Spec fields to their limits; the figures are
    :func:`pmsm2dof.studies.autotune.step_figures` of the trace's metrics, as autotune holds each
    simulated run. Returns ``{"limits", "figures", "misses", "met"}``: ``misses`` lists
    ``{"constraint", "limit", "value", "miss", "unit"}`` of the constraints missed, the largest miss
    relative to its limit (the binding one) first.

    Raises
    ------
    ConfigError
        A limit outside its valid range, or a constraint a trace does not show (naming it).
    """
    check_limits(limits)
    figures = step_figures(compute_metrics(trace))
    misses: list[dict[str, Any]] = []
    for name, limit in limits.items():
        figure, sense, unit = CONSTRAINTS[name]
        value = figures[figure]
        miss = value - limit if sense == "max" else limit - value
        if miss > 0.0:
            misses.append({"constraint": name, "limit": limit, "value": value, "miss": miss, "unit": unit})
    misses.sort(key=lambda m: -m["miss"] / (abs(m["limit"]) or 1.0))
    shown = {CONSTRAINTS[name][0]: _finite(figures[CONSTRAINTS[name][0]]) for name in limits}
    return {"limits": dict(limits), "figures": shown, "misses": _json_misses(misses), "met": not misses}


def check_limits(limits: dict[str, float]) -> None:
    """Raise ConfigError unless ``limits`` are valid constraints of :data:`TRACE_CONSTRAINTS` (as the Spec checks)."""
    for name, limit in limits.items():
        if name not in TRACE_CONSTRAINTS:
            raise ConfigError(name, limit, "one of " + ", ".join(TRACE_CONSTRAINTS) + " (what a trace shows)")
    checked: dict[str, Any] = dict(limits)
    Spec(min_phase_margin_deg=None, min_gain_margin_dB=None, **checked)


def _finite(x: float) -> float | None:
    """A figure for JSON: None for a step that never settled or recovered (inf)."""
    return x if math.isfinite(x) else None


def _json_misses(misses: list[dict[str, Any]]) -> list[dict[str, Any]]:
    return [{**m, "value": _finite(m["value"]), "miss": _finite(m["miss"])} for m in misses]


def check_drive_runs(link: Link, scenario: Scenario) -> None:
    """Raise ConfigError unless the drive's controllers run the scenario's configuration (float32, field by field)."""
    sim = Simulation(scenario).sim
    engine_cfg = {"link_speed_config": sim.speed.config, "link_current_config": sim.current.config}
    with link_errors(link, "reading the configuration"):
        for var, (ctype, _, _) in CONTROLLERS.items():
            if var not in link.variables:
                continue
            for s in link.variables[var].scalars:
                drive = link.read(s.name)
                mine = getattr(engine_cfg[var], s.field)
                if np.float32(drive) != np.float32(mine):
                    raise ConfigError(
                        "SCENARIO",
                        scenario.name,
                        f"the scenario the drive runs: its {s.name} is {drive!r}, the scenario's {float(mine)!r} "
                        f"({ctype}; rebuild the drive or set it back)",
                    )


def run_on_drive(
    link: Link, scenario: Scenario, *, way: str = "auto", link_bytes_per_s: float | None = None
) -> DriveRun:
    """Play ``scenario``'s reference (and load, on the virtual board) on the drive and simulate it with the engine.

    The run is captured from the firmware's signals (:func:`plan_run` with ``way`` and
    ``link_bytes_per_s``; :func:`capture_run`) at the scenario's speed samples.

    Raises
    ------
    ConfigError
        The drive runs another configuration, the scenario is longer than :data:`RUN_MAX_S`, or the
        link can capture it neither way.
    SimulationError
        The run did not end as done, or a sample was lost.
    ToolError
        The link dropped (the drive's watchdog stops the run).
    """
    t_end = scenario.simulation.t_end_s
    if t_end > RUN_MAX_S:
        raise ConfigError("simulation.t_end_s", t_end, f"at most {RUN_MAX_S:g} s for a run over the link")
    check_drive_runs(link, scenario)
    samples = math.floor(t_end / scenario.speed_controller.Ts_s + 1e-9) + 1
    with link_errors(link, "the run"):
        plan = plan_run(link, samples, way=way, link_bytes_per_s=link_bytes_per_s)
        start = time.perf_counter()
        drive = capture_run(link, scenario, plan, timeout_s=60.0 + WALL_S_PER_DRIVE_S * t_end)
        drive = dataclasses.replace(drive, wall_time_s=time.perf_counter() - start)
        after = link.status()
    if after["trip_sample"]:
        raise SimulationError(
            f"the link watchdog tripped the run at sample {after['trip_sample']} (the master was silent for longer "
            "than the drive's link timeout): the run is not the scenario's"
        )
    sim = Simulation(scenario)
    start = time.perf_counter()
    sim.advance(sim.n_samples)
    engine = sim.result(scenario, time.perf_counter() - start)
    return DriveRun(scenario=scenario, drive=drive, engine=engine, url=link.url, plan=plan)


def serve_drive(
    scenario: Scenario,
    out: Path | str,
    *,
    port: int,
    realtime: bool,
    timeout_ms: int,
    force: bool,
    duration_s: float | None,
    ready: Callable[[str, str], None],
) -> None:
    """Build the PC's virtual drive of ``scenario`` into ``out`` and serve it on 127.0.0.1:``port``.

    ``ready(url, a2l)`` is called once it listens (its link URL ``tcp://127.0.0.1:PORT`` and its A2L
    file); it serves for ``duration_s`` [s] or, when None, until interrupted
    (:func:`pmsm2dof.studies.firmware.serve_scenario`).
    """
    if duration_s is not None and not (math.isfinite(duration_s) and 0 < duration_s <= SERVE_MAX_S):
        raise ConfigError("duration_s", duration_s, f"(0, {SERVE_MAX_S:g}] s, or none: until interrupted")
    with serve_scenario(scenario, port=port, realtime=realtime, timeout_ms=timeout_ms, out=out, force=force) as (
        url,
        folder,
    ):
        ready("tcp://" + url.removeprefix("socket://"), str(folder / "virtual_drive_host.a2l"))
        end = time.monotonic() + (duration_s if duration_s is not None else math.inf)
        while time.monotonic() < end:
            time.sleep(min(0.1, max(0.0, end - time.monotonic())))
