"""Run a scenario in the compiled drive simulation engine.

The engine (``csrc/sim/drive.c``, double precision) simulates the drive of the paper's
Fig. 1: the PMSM of eq (1) with the amplitude-invariant torque
``Te = 1.5 p (psi_f iq + (Ld - Lq) id iq)`` (the paper's eq 1 omits the 1.5 and calls p0 the
number of poles while using it as pole pairs), the mechanics with viscous and Coulomb friction
and the load schedule, a switching-cycle average inverter limited to ``u_dc / sqrt(3)`` with an
optional one-sample computation delay, and either the dq current controllers (``dq_pi``) or the
first-order current loop of eq (3) (``first_order``). The speed controller (eq 9-15, Fig. 5, 6)
and the current controllers are the float32 C controllers of ``csrc/src``, the code that runs on
the MCU. A whole run is one C call (``p2d_sim_run``), so the GIL is released while it runs.

Arithmetic
    ``speed_controller.arithmetic`` ``q15`` or ``q31`` runs the fixed-point speed controller of
    ``speed_fixed.h`` (an MCU without an FPU) instead of the float32 one: the reference and the
    reading rounded to the nearest integer of the format, its current command ``iq`` in current
    LSBs. Its full scales are the ``speed_controller.*_full_scale_*`` keys or derived from the drive
    (:mod:`pmsm2dof.sim.engine_config`); :func:`pmsm2dof.analysis.fixedpoint.scaling_check` predicts what they do
    (the Q15 integrator's dead zone, the headroom). A surface PMSM only, without torque filters,
    field weakening or gain scheduling.

Sampling and integration
    The speed controller runs every ``speed_controller.Ts_s``, the current controller every
    ``current_loop.Ts_s``. The plant is integrated by the classical Runge-Kutta method (RK4) with
    the step ``current_loop.Ts_s / ceil(current_loop.Ts_s / simulation.dt_s)``: at most ``dt_s``
    and a whole fraction of the current period; a load step or ramp corner inside a step splits it.
    One RK4 step per current period (``dt_s = current_loop.Ts_s``) is accurate to far better than
    1e-4 of the speed for the paper's drive (tests/test_engine.py halves it).

Log
    One row per ``simulation.log_every`` speed-controller samples (``simulation.log_rate =
    "speed"``, the default) or current periods (``"current"``), starting at t = 0: the plant state
    at the row's instant, the outputs of the speed controller's last sample at or before it (its
    command, its integrator after the update, the reference and speed reading it sampled), the
    voltage applied over the current period that starts there (``first_order``: the voltage eq 1
    needs for the current slopes of eq 3, not limited) and the load torque. The rate chooses the
    rows and nothing else: the controllers run as they do at the speed rate, and the row of a speed
    sample is bit for bit the same at either rate. At the current rate the currents and voltages
    are seen over every current period (ripple, the voltage balance of eq 1 that
    :mod:`pmsm2dof.studies.electrical` fits); the log takes ``speed_controller.Ts_s /
    current_loop.Ts_s`` times the rows.

Faults
    The scenario's ``[[fault]]`` entries (:data:`pmsm2dof.core.FAULT_KINDS`): a DC-link sag
    scales ``u_dc`` over a window (the inverter's range and the DC link the current controller
    measures, per current period); a speed-sensor fault changes what the speed controller reads
    (held at the last reading, zero, or one wrong sample). The current controllers keep the true
    speed for their decoupling. A stall needs no fault: a load above the torque the current limit
    can give. ``speed_meas_rpm`` and ``u_dc_V`` of the :class:`Result` show what was read and applied.

Measurement and field weakening
    ``[speed_sensor]``: the speed controller reads the true speed or an encoder's counts (from the
    rotor angle the engine integrates) through the C estimator of ``encoder.h`` (difference or PLL),
    a low-pass, a transport delay and seeded noise. ``[current_measurement]``: the current
    controller reads the phase currents with gain errors, offsets and seeded noise, transformed to
    dq. ``[field_weakening]``: the voltage-feedback regulator of ``field_weakening.h`` sets the
    d-axis current at each speed sample from the current controller's voltage command, and the
    speed controller's torque limit follows the q current that remains (``p2d_speed_step_fw``).
    The defaults (ideal, exact, off) leave the loop as described above (csrc/sim/sensing.h).

Initial state
    In steady state at ``simulation.speed0_rpm`` with the reference equal to it and no
    load; the reference and load schedules apply from t = 0 (entries at t = 0 are steps at 0).

Drive train
    ``[mechanics]``: ``rigid`` (the default, one inertia ``motor.J_kgm2``) or ``two_mass``, the
    motor side ``motor.J_kgm2`` coupled to ``mechanics.J_load_kgm2`` by a shaft of stiffness,
    damping and play (a dead zone); the load torque acts on the load side, the friction on the
    motor side, and the speed controller reads the side ``mechanics.feedback`` names
    (``csrc/sim/drive.h`` has the equations). ``load_speed_rpm`` and ``shaft_torque_Nm`` of the
    :class:`Result` show the load side. ``[speed_filter]``: the speed controller's torque filters
    (a notch and a low-pass inside its anti-windup loop, ``csrc/include/pmsm2dof/filter.h``).

Coulomb friction
    ``T_coulomb_Nm tanh(w_m / w_c)`` with ``w_c = max(0.01 rad/s, 10 Ts_current T_c / J)``:
    smooth, with no stiction (a load below T_c lets the shaft creep slowly instead of holding).

Stops
    The engine stops, and :func:`simulate` raises :class:`~pmsm2dof.errors.SimulationError`
    with the time and the reason, when the state becomes non-finite, the speed exceeds twice the
    no-load speed ``u_dc / (sqrt(3) p psi_f)``, or the current exceeds ten times the larger of
    ``i_max_A`` and the short-circuit current ``psi_f / min(Ld, Lq)``.

Many runs
    :func:`simulate_many` runs scenarios of one shape (the same current period, speed period,
    integration step, log interval, duration, current-loop model, drive train and presence of
    Coulomb friction) in lockstep: ``P2D_SIM_LANES`` drives share one C loop, their plants' states
    in an array per state variable, so that the compiler vectorises the RK4 step across them
    (``p2d_sim_run_many``). Every trace is bit for bit the one :func:`simulate` gives.
"""

import dataclasses
import math
import time
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar, NoReturn

import numpy as np
import numpy.typing as npt

from ..core import (
    LOG_COLUMNS,
)
from ..core.bindings import c_string, ffi, lib
from ..errors import ConfigError, SimulationError, format_bytes
from ..outputs import atomic_file
from .engine_config import engine_config, full_scales, raise_config_error
from .engine_keys import RPM_PER_RADPS as RPM_PER_RADPS  # the speed unit at the edge, for the callers
from .plausibility import peak_torque_Nm
from .scenario import Scenario

if TYPE_CHECKING:
    import pandas as pd

#: Rows of the CSV trace formatted at a time (about 11 MB of text, 45 MiB of Python strings for the
#: engine's 24 columns; benchmarks/results.md, "Bounds on the work an input asks for").
CSV_ROWS_PER_CHUNK = 50_000

#: The speeds of the engine's log shown in rpm at the edge, by log column (the others keep their
#: C names); the mechanical speed is kept in rad/s too.
RPM_SIGNALS = {
    "w_ref_radps": "speed_ref_rpm",
    "w_m_radps": "speed_rpm",
    "w_meas_radps": "speed_meas_rpm",
    "w_load_radps": "load_speed_rpm",
}
#: Log columns that hold a flag (0 or 1), returned as bool arrays.
FLAG_SIGNALS = ("saturated", "J_valid")


def _signal_names(log_columns: Iterable[str]) -> tuple[str, ...]:
    """The signals of a :class:`Result`, in order, from the columns of the engine's log."""
    names: list[str] = []
    for column in log_columns:
        names.append(RPM_SIGNALS.get(column, column))
        if column == "w_m_radps":
            names.append(column)
    return tuple(names)


#: Largest log the engine allocates [bytes]; beyond it simulation.log_every must grow.
LOG_BYTES_MAX = 2 * 1024**3

#: Most RK4 steps per current period (simulation.dt_s >= current_loop.Ts_s / this).
SUBSTEPS_MAX = 10**6

#: Most current periods per speed period (speed_controller.Ts_s <= this * current_loop.Ts_s).
CURRENT_PER_SPEED_MAX = 10**6

#: Number of C calls a run is split into when the progress bar is on.
PROGRESS_CHUNKS = 200

#: Fewest current periods of a run that gets a progress bar (fewer take well under the bar's 1 s delay: the
#: engine runs about 5 million per second).
PROGRESS_PERIODS_MIN = 2 * 10**6


@dataclasses.dataclass(frozen=True, eq=False, repr=False)
class Result:
    """The trace of one simulation: numpy arrays of equal length, one per signal.

    Attributes
    ----------
    scenario : Scenario
        The scenario simulated.
    wall_time_s : float
        Wall-clock time of the run [s].
    t_s : time of the row [s]: a speed-controller sampling instant, or the start of a current period
        (``simulation.log_rate = "current"``)
    speed_ref_rpm : speed reference sampled by the speed controller [rpm]
    speed_rpm, w_m_radps : mechanical speed [rpm], [rad/s]
    id_ref_A, iq_ref_A : current command of the speed controller [A]
    id_A, iq_A : dq currents [A]
    ud_V, uq_V : dq voltage applied over the next current period [V] (``first_order``: the
        voltage eq 1 needs for the current slopes of eq 3, not limited)
    torque_Nm : electromagnetic torque 1.5 p (psi_f iq + (Ld - Lq) id iq) [Nm]
    torque_ref_Nm : speed controller output u_sat, after the current limit [Nm]
    torque_unsat_Nm : speed controller output u before the limit [Nm]
    load_Nm : load torque [Nm]
    saturated : the current-vector limit is active (bool)
    x_i_Nm : integrator of the speed PI after the sample's update [Nm]
    speed_meas_rpm : speed reading sampled by the speed controller: the ``[speed_sensor]``'s reading
        (encoder estimate, low-pass, delay, noise; the true speed with the default ideal sensor), or a
        sensor fault's [rpm]
    u_dc_V : DC-link voltage over the current period that starts at the row (nominal but under a
        DC-link sag) [V]
    voltage_limited : share of the current periods of the row's speed sample whose voltage was cut
        to the inverter's range ``u_dc / sqrt(3)`` [-], in [0, 1] (``first_order``: whose voltage of
        eq 1 exceeded that range, which eq 3 ignores); at the current rate every row of a speed
        sample holds its share
    load_speed_rpm : load-side speed of the two-mass train [rpm] (rigid: speed_rpm)
    shaft_torque_Nm : torque the shaft carries from motor to load [Nm] (rigid: load_Nm)
    """

    #: The signal names, in order: the engine's log columns (p2d_sim_log_name), speeds in rpm.
    signals: ClassVar[tuple[str, ...]] = _signal_names(LOG_COLUMNS)

    scenario: Scenario
    wall_time_s: float
    t_s: npt.NDArray[np.float64]
    speed_ref_rpm: npt.NDArray[np.float64]
    speed_rpm: npt.NDArray[np.float64]
    w_m_radps: npt.NDArray[np.float64]
    id_ref_A: npt.NDArray[np.float64]
    iq_ref_A: npt.NDArray[np.float64]
    id_A: npt.NDArray[np.float64]
    iq_A: npt.NDArray[np.float64]
    ud_V: npt.NDArray[np.float64]
    uq_V: npt.NDArray[np.float64]
    torque_Nm: npt.NDArray[np.float64]
    torque_ref_Nm: npt.NDArray[np.float64]
    torque_unsat_Nm: npt.NDArray[np.float64]
    load_Nm: npt.NDArray[np.float64]
    saturated: npt.NDArray[np.bool_]
    x_i_Nm: npt.NDArray[np.float64]
    speed_meas_rpm: npt.NDArray[np.float64]
    u_dc_V: npt.NDArray[np.float64]
    voltage_limited: npt.NDArray[np.float64]
    J_est_kgm2: npt.NDArray[np.float64]
    J_valid: npt.NDArray[np.bool_]
    T_load_est_Nm: npt.NDArray[np.float64]
    J_gains_kgm2: npt.NDArray[np.float64]
    load_speed_rpm: npt.NDArray[np.float64]
    shaft_torque_Nm: npt.NDArray[np.float64]

    def __repr__(self) -> str:
        return (
            f"Result({self.scenario.name!r}, {len(self.t_s)} rows, t = {self.t_s[0]:g}..{self.t_s[-1]:g} s, "
            f"wall {self.wall_time_s:.3g} s)"
        )

    def to_dataframe(self) -> "pd.DataFrame":
        """The signals as a pandas DataFrame, one column per signal in :attr:`signals` order."""
        import pandas as pd

        return pd.DataFrame({name: getattr(self, name) for name in self.signals})

    def save(self, path: Path | str) -> None:
        """Write the trace to ``path``; the format follows the extension.

        ``.csv``: one column per signal with a header row (the flags ``saturated`` and ``J_valid`` as 0/1);
        ``.npz`` (numpy) and ``.mat`` (MATLAB, ``scipy.io.savemat``): one array per signal
        and ``scenario_toml``, the scenario as TOML text. The file is written completely or
        not at all, streamed to the disk (the CSV text :data:`CSV_ROWS_PER_CHUNK` rows at a time),
        so that the log of a long run is never held twice in memory; a full disk raises a
        ConfigError naming ``path`` (:func:`pmsm2dof.outputs.atomic_file`).
        """

        path = Path(path)
        suffix = path.suffix.lower()
        arrays = {name: getattr(self, name) for name in self.signals}
        if suffix == ".csv":
            with atomic_file(path, "w") as f:
                f.write(",".join(self.signals) + "\n")
                for start in range(0, len(self.t_s), CSV_ROWS_PER_CHUNK):
                    rows = slice(start, start + CSV_ROWS_PER_CHUNK)
                    columns = [
                        _csv_column(arrays[name][rows].astype(np.int8) if name in FLAG_SIGNALS else arrays[name][rows])
                        for name in self.signals
                    ]
                    f.write("".join(",".join(row) + "\n" for row in zip(*columns)))
        elif suffix == ".npz":
            with atomic_file(path, "wb") as f:
                np.savez(f, scenario_toml=np.array(self.scenario.to_toml()), **arrays)
        elif suffix == ".mat":
            import scipy.io

            with atomic_file(path, "wb") as f:
                scipy.io.savemat(f, {"scenario_toml": self.scenario.to_toml(), **arrays}, oned_as="column")
        else:
            raise ConfigError("path", str(path), "a file name ending in .csv, .npz or .mat")


def _csv_column(values: npt.NDArray[Any]) -> list[str]:
    """The texts of a column of the CSV trace: each number as Python writes it (``repr``, the shortest
    text that reads back the same value), a value that repeats (a schedule, a flag) formatted once."""
    distinct, index = np.unique(values, return_inverse=True)
    if 4 * distinct.size < values.size:
        texts: list[str] = np.array([repr(v) for v in distinct.tolist()], dtype=object)[index].tolist()
        return texts
    return list(map(repr, values.tolist()))


def simulate(scenario: Scenario, progress: bool = False) -> "Result":
    """Simulate ``scenario`` in the compiled engine and return its :class:`Result`.

    Parameters
    ----------
    scenario : Scenario
        A validated scenario (:func:`pmsm2dof.sim.scenario.load_scenario`, ``Scenario.from_dict``).
        The speed controller is designed (eq 9, 11) for ``speed_controller.J_kgm2`` and
        ``speed_controller.tau_i_s``; the plant uses ``motor.J_kgm2`` and ``current_loop.tau_i_s``.
        ``speed_controller.Ka`` None means the paper's 1/Kp (section 3.3).
    progress : bool
        Show a progress bar on stderr when the run lasts more than a second (runs of fewer than
        :data:`PROGRESS_PERIODS_MIN` current periods never do, and do not load the bar).

    Raises
    ------
    ConfigError
        A value the C controllers or the engine reject, naming the scenario key.
    SimulationError
        The run stopped: non-finite state, overspeed or overcurrent (time and reason given).
    """
    if not isinstance(scenario, Scenario):
        raise ConfigError(
            "scenario", type(scenario).__name__, "a pmsm2dof Scenario (load_scenario or Scenario.from_dict)"
        )
    run = Simulation(scenario)
    start = time.perf_counter()
    if progress and run.n_samples * run.current_per_speed >= PROGRESS_PERIODS_MIN:
        from tqdm import tqdm

        chunk = max(1, math.ceil(run.n_samples / PROGRESS_CHUNKS))
        with tqdm(
            total=scenario.simulation.t_end_s,
            unit="s",
            unit_scale=True,
            delay=1.0,
            desc=f"simulating {scenario.name}",
            leave=False,
        ) as bar:
            done = 0
            while done < run.n_samples:
                n = min(chunk, run.n_samples - done)
                run.advance(n)
                done += n
                bar.update(n * run.Ts_speed_s)
    else:
        run.advance(run.n_samples)
    return run.result(scenario, time.perf_counter() - start)


def simulate_many(scenarios: Sequence[Scenario]) -> list["Result | SimulationError"]:
    """Simulate ``scenarios`` in the compiled engine, those of one shape in lockstep.

    Scenarios of one shape (see the module docstring) run in groups of ``P2D_SIM_LANES`` through one
    C call each (``p2d_sim_run_many``, the GIL released), the others alone; each trace is bit for
    bit the :class:`Result` of :func:`simulate`.

    Parameters
    ----------
    scenarios : sequence of Scenario
        Validated scenarios; their logs together may take at most :data:`LOG_BYTES_MAX`.

    Returns
    -------
    list
        In the order of ``scenarios``: the :class:`Result` of each, or the
        :class:`~pmsm2dof.errors.SimulationError` that stopped it (not raised, so that the others
        are kept). ``Result.wall_time_s`` is the wall time of its group's C call shared equally
        among the group's drives.

    Raises
    ------
    ConfigError
        A value the C controllers or the engine reject, naming the scenario key; the logs of all
        scenarios beyond :data:`LOG_BYTES_MAX`.
    """
    for scenario in scenarios:
        if not isinstance(scenario, Scenario):
            raise ConfigError(
                "scenarios", type(scenario).__name__, "pmsm2dof Scenarios (load_scenario or Scenario.from_dict)"
            )
    total = sum(log_rows(s)[1] * lib.P2D_LOG_COUNT * 8 for s in scenarios)
    if total > LOG_BYTES_MAX:
        raise ConfigError(
            "scenarios",
            f"{len(scenarios)} scenarios whose logs take {total / 1024**3:.3g} GiB",
            f"logs of at most {LOG_BYTES_MAX / 1024**3:g} GiB in all: simulate them in smaller groups",
        )
    runs = [Simulation(s) for s in scenarios]
    # the engine decides who runs in lockstep (p2d_sim_lockstep): with the first of a group, the same samples
    groups: list[list[int]] = []
    for i, run in enumerate(runs):
        for g in groups:
            first = runs[g[0]]
            if first.n_samples == run.n_samples and lib.p2d_sim_lockstep(first.sim, run.sim):
                g.append(i)
                break
        else:
            groups.append([i])
    outcomes: list[Result | SimulationError | None] = [None] * len(runs)
    for members in groups:
        for start in range(0, len(members), lib.P2D_SIM_LANES):
            chunk = members[start : start + lib.P2D_SIM_LANES]
            group = [runs[i] for i in chunk]
            sims = ffi.new("p2d_sim_t *[]", [r.sim for r in group])
            logs = ffi.new("double *[]", [r._log_ptr for r in group])
            rows = ffi.new("uint64_t[]", [r.log.shape[1] for r in group])
            t0 = time.perf_counter()
            status = lib.p2d_sim_run_many(sims, len(group), group[0].n_samples, logs, rows)
            wall_s = (time.perf_counter() - t0) / len(group)
            if status != lib.P2D_SIM_OK:
                raise RuntimeError(f"p2d_sim_run_many: {c_string(lib.p2d_sim_status_text(status))}")
            for i, run in zip(chunk, group):
                stopped = run.sim.status
                outcomes[i] = run.stop_error(stopped) if stopped != lib.P2D_SIM_OK else run.result(scenarios[i], wall_s)
    return [o for o in outcomes if o is not None]


def log_rows(scenario: Scenario) -> tuple[int, int]:
    """The speed samples of ``scenario`` and the rows of its log (at its ``simulation.log_rate``)."""
    sim = scenario.simulation
    n_samples = math.floor(sim.t_end_s / scenario.speed_controller.Ts_s + 1e-9) + 1
    return n_samples, -(-row_periods(scenario, n_samples) // sim.log_every)


def row_periods(scenario: Scenario, n_samples: int) -> int:
    """The speed samples (log rate ``speed``) or current periods (``current``) of ``n_samples`` speed samples."""
    if scenario.simulation.log_rate == "speed":
        return n_samples
    per_speed: int = round(scenario.speed_controller.Ts_s / scenario.current_loop.Ts_s)
    return n_samples * per_speed


class Simulation:
    """One engine instance: the C configuration built from a scenario, the state and the log.

    :func:`simulate` runs it whole; a caller that wants to stop between parts of a run (the
    tuner) calls :meth:`advance` in chunks, then :meth:`signals`.

    Parameters
    ----------
    scenario : Scenario
        A validated scenario.

    Raises
    ------
    ConfigError
        A value the C controllers or the engine reject, naming the scenario key.
    """

    def __init__(self, scenario: Scenario) -> None:
        self.scenario = scenario
        cl, sc, sim = scenario.current_loop, scenario.speed_controller, scenario.simulation
        self.Ts_speed_s = sc.Ts_s
        self.current_per_speed = current_per_speed = round(sc.Ts_s / cl.Ts_s)
        if current_per_speed > CURRENT_PER_SPEED_MAX:
            raise ConfigError(
                "speed_controller.Ts_s",
                sc.Ts_s,
                f"<= {CURRENT_PER_SPEED_MAX:g} current_loop.Ts_s = {cl.Ts_s * CURRENT_PER_SPEED_MAX:g} s",
            )
        substeps = max(1, math.ceil(cl.Ts_s / sim.dt_s * (1.0 - 1e-9)))
        if substeps > SUBSTEPS_MAX:
            raise ConfigError(
                "simulation.dt_s",
                sim.dt_s,
                f">= current_loop.Ts_s / {SUBSTEPS_MAX:g} = {cl.Ts_s / SUBSTEPS_MAX:g} s",
            )
        self.n_samples, rows = log_rows(scenario)
        self._periods = row_periods(scenario, self.n_samples)
        # the rows to t_end_s: at the current rate the periods of the last speed sample after t_end_s are left out
        self._rows_to_end = (self._periods - self._periods // self.n_samples) // sim.log_every + 1
        if rows * lib.P2D_LOG_COUNT * 8 > LOG_BYTES_MAX:
            least = -(-self._periods * lib.P2D_LOG_COUNT * 8 // LOG_BYTES_MAX)
            raise ConfigError(
                "simulation.log_every",
                sim.log_every,
                f">= {least}: the log of {rows} rows{self._rate_text()} would exceed {LOG_BYTES_MAX / 1024**3:g} GiB",
            )

        cfg, self._arrays = engine_config(scenario, current_per_speed, substeps)
        #: The full scales of the fixed-point speed controller by C field name ({} for float32).
        self.full_scales = full_scales(cfg)
        self.cfg = cfg
        self.sim = ffi.new("p2d_sim_t *")
        status = lib.p2d_sim_init(self.sim, cfg)
        if status != lib.P2D_SIM_OK:
            self._raise_config(status)
        # column-major: one contiguous array per signal
        try:
            self.log = np.zeros((lib.P2D_LOG_COUNT, rows))
        except MemoryError:
            least = -(-self._periods * lib.P2D_LOG_COUNT * 8 // (LOG_BYTES_MAX // 8))
            raise ConfigError(
                "simulation.log_every",
                sim.log_every,
                f"large enough for the log to fit in the memory this process may use: {rows} rows"
                f"{self._rate_text()} need {format_bytes(rows * lib.P2D_LOG_COUNT * 8)} (log_every >= {least} "
                "keeps it below "
                f"{format_bytes(LOG_BYTES_MAX // 8)})",
            ) from None
        self._log_ptr = ffi.cast("double *", ffi.from_buffer(self.log))

    def _rate_text(self) -> str:
        """How the rows of a log at the current rate come about, for a message ("" at the speed rate)."""
        if self.scenario.simulation.log_rate == "speed":
            return ""
        return (
            f" (simulation.log_rate = 'current': a row every {self.scenario.simulation.log_every} of the "
            f"{self._periods} current periods, {self.current_per_speed} per speed sample)"
        )

    def advance(self, n_samples: int) -> None:
        """Run ``n_samples`` speed-controller samples (one C call, GIL released)."""
        status = lib.p2d_sim_run(self.sim, n_samples, self._log_ptr, self.log.shape[1])
        if status != lib.P2D_SIM_OK:
            raise self.stop_error(status)

    def signals(self) -> dict[str, npt.NDArray[Any]]:
        """The log so far as the named arrays of :class:`Result`, rpm at the edge (:data:`RPM_SIGNALS`)."""
        return log_signals(self.log[:, : min(self.sim.n_rows, self._rows_to_end)])

    def result(self, scenario: Scenario, wall_time_s: float) -> Result:
        """The :class:`Result` of the log so far, for ``scenario`` (the one this run was built from)."""
        return Result(scenario=scenario, wall_time_s=wall_time_s, **self.signals())

    def _raise_config(self, status: int) -> NoReturn:
        """Raise the ConfigError of the init status ``status``, naming the scenario key (:func:`raise_config_error`)."""
        raise_config_error(status, self.sim, self.cfg, self.scenario)

    def stop_error(self, status: int) -> SimulationError:
        """The SimulationError of the stop ``status`` (a ``P2D_SIM_STOP_*`` code) of this run."""
        sim = self.sim
        reason = c_string(lib.p2d_sim_status_text(status))
        if status == lib.P2D_SIM_STOP_OVERSPEED:
            reason += f": |speed| = {sim.stop_value * RPM_PER_RADPS:.6g} rpm > {sim.stop_bound * RPM_PER_RADPS:.6g} rpm"
            motor, i_max_A = self.scenario.motor, self.scenario.limits.i_max_A
            T_peak = peak_torque_Nm(i_max_A, motor.pole_pairs, motor.psi_f_Wb, motor.Ld_H, motor.Lq_H)
            over = [
                (i, e) for i, e in enumerate(self.scenario.load) if e.t_s <= sim.t_stop_s and abs(e.torque_Nm) > T_peak
            ]
            if over:
                i, e = over[-1]
                reason = (
                    f"the load load.{i}.torque_Nm = {e.torque_Nm:.6g} Nm is above the peak torque {T_peak:.4g} "
                    f"Nm that limits.i_max_A = {i_max_A:g} A gives: it stalled the drive and turned it backwards "
                    f"({reason})"
                )
        elif status == lib.P2D_SIM_STOP_OVERCURRENT:
            reason += f": ||i_dq|| = {sim.stop_value:.6g} A > {sim.stop_bound:.6g} A"
        return SimulationError(f"simulation of {self.scenario.name!r} stopped at t = {sim.t_stop_s:.6g} s: {reason}")


def log_signals(log: npt.NDArray[np.float64]) -> dict[str, npt.NDArray[Any]]:
    """The named arrays of :class:`Result` from a log of the engine's columns (one row per column).

    ``log[i]`` is the column :data:`pmsm2dof.core.LOG_COLUMNS` ``[i]`` (the engine's, or a trace in its
    format); speeds become rpm at the edge (:data:`RPM_SIGNALS`), flags bool arrays.

    Raises
    ------
    SimulationError
        A value of the log is not finite.
    """
    col = {name: log[i] for i, name in enumerate(LOG_COLUMNS)}
    bad = [name for name, a in col.items() if not np.all(np.isfinite(a))]
    if bad:
        first = min(int(np.argmin(np.isfinite(col[name]))) for name in bad)
        raise SimulationError(f"non-finite values in the log ({', '.join(bad)}) from t = {col['t_s'][first]:.6g} s")
    signals: dict[str, npt.NDArray[Any]] = {}
    for name, values in col.items():
        if name in RPM_SIGNALS:
            signals[RPM_SIGNALS[name]] = values * RPM_PER_RADPS
            if name == "w_m_radps":
                signals[name] = values
        else:
            signals[name] = values != 0.0 if name in FLAG_SIGNALS else values
    return signals
