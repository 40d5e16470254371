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
    (:func:`_arithmetic`); :func:`pmsm2dof.analysis.fixedpoint.scaling_check` predicts what they do
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
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
import numpy.typing as npt

from ..core import (
    ANTI_WINDUPS,
    ARITHMETICS,
    CURRENT_LOOP_MODELS,
    ESTIMATORS,
    FAULT_KINDS,
    FEEDBACKS,
    FEEDFORWARDS,
    LOG_COLUMNS,
    LOG_RATES,
    MECHANICS_MODELS,
    METHODS,
    SPEED_SENSOR_MODELS,
    pi_gains,
)
from ..core.bindings import c_string, ffi, lib
from ..core.controllers import float32_note
from ..core.gains import default_Ka_error
from ..errors import ConfigError, SimulationError, format_bytes
from ..outputs import atomic_file
from .datasheet import no_load_speed_radps
from .plausibility import peak_torque_Nm
from .scenario import SCHEMA, SameAs, Scenario, Tree

if TYPE_CHECKING:
    import pandas as pd

RPM_PER_RADPS = 30.0 / math.pi
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

#: Scenario key of each field that the C speed controller init can reject (p2d_status_param).
_SPEED_KEYS = {
    "J_kgm2": "speed_controller.J_kgm2",
    "alpha_radps": "speed_controller.alpha_radps",
    "zeta": "speed_controller.zeta",
    "m": "speed_controller.m",
    "tau_i_s": "speed_controller.tau_i_s",
    "Ka": "speed_controller.Ka",
    "Ts_s": "speed_controller.Ts_s",
    "i_max_A": "limits.i_max_A",
    "psi_f_Wb": "motor.psi_f_Wb",
    "Ld_H": "motor.Ld_H",
    "Lq_H": "motor.Lq_H",
    "pole_pairs": "motor.pole_pairs",
    "method": "speed_controller.method",
    "feedforward": "speed_controller.feedforward",
    "anti_windup": "speed_controller.anti_windup",
    "notch_freq_Hz": "speed_filter.notch_freq_Hz",
    "notch_width_Hz": "speed_filter.notch_width_Hz",
    "notch_depth": "speed_filter.notch_depth",
    "lowpass_freq_Hz": "speed_filter.lowpass_freq_Hz",
    "lowpass_zeta": "speed_filter.lowpass_zeta",
    "speed_full_scale_radps": "speed_controller.speed_full_scale_rpm",
    "torque_full_scale_Nm": "speed_controller.torque_full_scale_Nm",
    "current_full_scale_A": "speed_controller.current_full_scale_A",
}

#: Scenario key of each field that the C current controller init can reject.
_CURRENT_KEYS = {
    "Rs_ohm": "motor.Rs_ohm",
    "Ld_H": "motor.Ld_H",
    "Lq_H": "motor.Lq_H",
    "psi_f_Wb": "motor.psi_f_Wb",
    "tau_i_s": "current_loop.tau_i_s",
    "Ts_s": "current_loop.Ts_s",
    "method": "current_loop.method",
    "anti_windup": "current_loop.anti_windup",
}

#: Scenario key of each field that the C encoder (speed_sensor) or field weakening init can reject.
_SENSING_KEYS = {
    "counts_per_rev": "speed_sensor.counts_per_rev",
    "counter_bits": "speed_sensor.counter_bits",
    "estimator": "speed_sensor.estimator",
    "bandwidth_radps": "speed_sensor.bandwidth_radps",
    "lowpass_radps": "speed_sensor.lowpass_radps",
    "Ts_s": "speed_controller.Ts_s",
    "Kp_A_per_V": "field_weakening.Kp_A_per_V",
    "Ki_A_per_Vs": "field_weakening.Ki_A_per_Vs",
    "Ka_V_per_A": "field_weakening.Ka_V_per_A",
    "voltage_ratio": "field_weakening.voltage_ratio",
    "id_min_A": "field_weakening.id_min_A",
}

#: Scenario key of each field that p2d_sim_init can reject (p2d_sim_status_param).
_SIM_KEYS = {
    "motor.pole_pairs": "motor.pole_pairs",
    "motor.Rs_ohm": "motor.Rs_ohm",
    "motor.Ld_H": "motor.Ld_H",
    "motor.Lq_H": "motor.Lq_H",
    "motor.psi_f_Wb": "motor.psi_f_Wb",
    "motor.J_kgm2": "motor.J_kgm2",
    "motor.B_Nms": "motor.B_Nms",
    "motor.T_coulomb_Nm": "motor.T_coulomb_Nm",
    "u_dc_V": "limits.u_dc_V",
    "current_model": "current_loop.model",
    "tau_i_s": "current_loop.tau_i_s",
    "Ts_current_s": "current_loop.Ts_s",
    "current_per_speed": "speed_controller.Ts_s",
    "substeps": "simulation.dt_s",
    "log_every": "simulation.log_every",
    "log_rate": "simulation.log_rate",
    "w_m0_radps": "simulation.speed0_rpm",
    "reference": "reference",
    "load": "load",
    "faults": "fault",
    "adapt.adapt_rel_change": "estimator.adapt_rel_change",
    "adapt.e_quiet_radps": "estimator.adapt_error_rpm",
    "speed_sensor": "speed_sensor",
    "current_sensor": "current_measurement",
    "field_weakening": "field_weakening",
    "mechanics.model": "mechanics.model",
    "mechanics.J_load_kgm2": "mechanics.J_load_kgm2",
    "mechanics.stiffness_Nm_per_rad": "mechanics.stiffness_Nm_per_rad",
    "mechanics.damping_Nms_per_rad": "mechanics.damping_Nms_per_rad",
    "mechanics.backlash_rad": "mechanics.backlash_rad",
    "mechanics.feedback": "mechanics.feedback",
    "arithmetic": "speed_controller.arithmetic",
}

#: Scenario key of each field that the C inertia estimator init can reject (the estimator block).
_ESTIMATOR_KEYS = {
    name: f"estimator.{name}"
    for name in (
        "J0_kgm2",
        "J_min_kgm2",
        "J_max_kgm2",
        "B_max_Nms",
        "T_load_max_Nm",
        "sigma_T_Nm",
        "J_memory_s",
        "load_memory_s",
        "w_f_radps",
        "J_rel_sd_max",
    )
} | {"Ts_s": "speed_controller.Ts_s"}


#: Keys whose absent value the engine takes from another key: key -> (that key, how). An error of the
#: engine names the key the user set: the SameAs defaults of the schema and the derived defaults of
#: [estimator] and [field_weakening] (``speed_controller.Ka``, 1/Kp, is named by what makes it fail:
#: :func:`pmsm2dof.core.gains.default_Ka_error`).
_SAME_AS = {f.key: f.default.key for f in SCHEMA if isinstance(f.default, SameAs)}
_SOURCES = {key: (source, source) for key, source in _SAME_AS.items()} | {
    "estimator.J_min_kgm2": ("estimator.J0_kgm2", "J0_kgm2 / 10"),
    "estimator.J_max_kgm2": ("estimator.J0_kgm2", "10 J0_kgm2"),
    "estimator.B_max_Nms": ("limits.i_max_A", "the peak torque 1.5 p psi_f i_max_A per 100 rad/s"),
    "estimator.T_load_max_Nm": ("limits.i_max_A", "the peak torque 1.5 p psi_f i_max_A"),
    "estimator.sigma_T_Nm": ("limits.i_max_A", "1 % of the peak torque 1.5 p psi_f i_max_A"),
    "estimator.load_memory_s": ("speed_controller.alpha_radps", "1 / alpha_radps"),
    "estimator.w_f_radps": ("speed_controller.Ts_s", "0.2 / Ts_s"),
    "field_weakening.Ka_V_per_A": ("field_weakening.Ki_A_per_Vs", "1 / (Ki_A_per_Vs speed_controller.Ts_s)"),
    "field_weakening.id_min_A": ("limits.i_max_A", "-i_max_A"),
    "speed_controller.speed_full_scale_rpm": ("limits.u_dc_V", "twice the no-load speed u_dc_V / (sqrt(3) p psi_f)"),
    "speed_controller.torque_full_scale_Nm": (
        "limits.i_max_A",
        "1.25 times the smallest that holds the torque limit 1.5 p psi_f i_max_A, the feedforward's state and "
        "transient at the references and the command at the largest reference step",
    ),
    "speed_controller.current_full_scale_A": (
        "speed_controller.torque_full_scale_Nm",
        "torque_full_scale_Nm / (1.5 p psi_f)",
    ),
}


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
    data = scenario.data
    run = Simulation(data)
    start = time.perf_counter()
    if progress and run.n_samples * run.current_per_speed >= PROGRESS_PERIODS_MIN:
        from tqdm import tqdm

        chunk = max(1, math.ceil(run.n_samples / PROGRESS_CHUNKS))
        with tqdm(
            total=data["simulation"]["t_end_s"],
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
    total = sum(log_rows(s.data)[1] * lib.P2D_LOG_COUNT * 8 for s in scenarios)
    if total > LOG_BYTES_MAX:
        raise ConfigError(
            "scenarios",
            f"{len(scenarios)} scenarios whose logs take {total / 1024**3:.3g} GiB",
            f"logs of at most {LOG_BYTES_MAX / 1024**3:g} GiB in all: simulate them in smaller groups",
        )
    runs = [Simulation(s.data) for s in scenarios]
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


def log_rows(data: Tree) -> tuple[int, int]:
    """The speed samples of the scenario data ``data`` and the rows of its log (at its ``simulation.log_rate``)."""
    sc, sim = data["speed_controller"], data["simulation"]
    n_samples = math.floor(sim["t_end_s"] / sc["Ts_s"] + 1e-9) + 1
    return n_samples, -(-row_periods(data, n_samples) // sim["log_every"])


def row_periods(data: Tree, n_samples: int) -> int:
    """The speed samples (log rate ``speed``) or current periods (``current``) of ``n_samples`` speed samples."""
    if data["simulation"]["log_rate"] == "speed":
        return n_samples
    per_speed: int = round(data["speed_controller"]["Ts_s"] / data["current_loop"]["Ts_s"])
    return n_samples * per_speed


class Simulation:
    """One engine instance: the C configuration built from scenario data, the state and the log.

    :func:`simulate` runs it whole; a caller that wants to stop between parts of a run (the
    tuner) calls :meth:`advance` in chunks, then :meth:`signals`.

    Parameters
    ----------
    data : dict
        :attr:`Scenario.data` of a validated scenario.

    Raises
    ------
    ConfigError
        A value the C controllers or the engine reject, naming the scenario key.
    """

    def __init__(self, data: Tree) -> None:
        self.data = data
        motor, limits, cl, sc, sim = (
            data[k] for k in ("motor", "limits", "current_loop", "speed_controller", "simulation")
        )
        self.Ts_speed_s = sc["Ts_s"]
        self.current_per_speed = current_per_speed = round(sc["Ts_s"] / cl["Ts_s"])
        if current_per_speed > CURRENT_PER_SPEED_MAX:
            raise ConfigError(
                "speed_controller.Ts_s",
                sc["Ts_s"],
                f"<= {CURRENT_PER_SPEED_MAX:g} current_loop.Ts_s = {cl['Ts_s'] * CURRENT_PER_SPEED_MAX:g} s",
            )
        substeps = max(1, math.ceil(cl["Ts_s"] / sim["dt_s"] * (1.0 - 1e-9)))
        if substeps > SUBSTEPS_MAX:
            raise ConfigError(
                "simulation.dt_s",
                sim["dt_s"],
                f">= current_loop.Ts_s / {SUBSTEPS_MAX:g} = {cl['Ts_s'] / SUBSTEPS_MAX:g} s",
            )
        self.n_samples, rows = log_rows(data)
        self._periods = row_periods(data, self.n_samples)
        # the rows to t_end_s: at the current rate the periods of the last speed sample after t_end_s are left out
        self._rows_to_end = (self._periods - self._periods // self.n_samples) // sim["log_every"] + 1
        if rows * lib.P2D_LOG_COUNT * 8 > LOG_BYTES_MAX:
            least = -(-self._periods * lib.P2D_LOG_COUNT * 8 // LOG_BYTES_MAX)
            raise ConfigError(
                "simulation.log_every",
                sim["log_every"],
                f">= {least}: the log of {rows} rows{self._rate_text()} would exceed {LOG_BYTES_MAX / 1024**3:g} GiB",
            )

        cfg = ffi.new("p2d_sim_config_t *")
        m = cfg.motor
        m.pole_pairs = motor["pole_pairs"]
        for key in ("Rs_ohm", "Ld_H", "Lq_H", "psi_f_Wb", "J_kgm2", "B_Nms", "T_coulomb_Nm"):
            setattr(m, key, motor[key])
        cfg.u_dc_V = limits["u_dc_V"]
        cfg.computation_delay = data["inverter"]["computation_delay"]
        cfg.current_model = CURRENT_LOOP_MODELS.index(cl["model"])
        cfg.tau_i_s = cl["tau_i_s"]
        cfg.Ts_current_s = cl["Ts_s"]
        cfg.current_per_speed = current_per_speed
        cfg.substeps = substeps
        cfg.log_every = sim["log_every"]
        cfg.log_rate = LOG_RATES.index(sim["log_rate"])
        cfg.w_m0_radps = sim["speed0_rpm"] / RPM_PER_RADPS
        self._schedules = [
            _schedule(cfg.reference, data["reference"], "speed_rpm", 1.0 / RPM_PER_RADPS),
            _schedule(cfg.load, data["load"], "torque_Nm", 1.0),
        ]
        self._faults = _faults(cfg, data["fault"])
        _mechanics(cfg, data["mechanics"], data["speed_filter"])

        s = cfg.speed
        s.J_kgm2 = sc["J_kgm2"]
        s.alpha_radps = sc["alpha_radps"]
        s.zeta = sc["zeta"]
        s.m = sc["m"]
        s.tau_i_s = sc["tau_i_s"]
        s.Ts_s = sc["Ts_s"]
        s.i_max_A = limits["i_max_A"]
        s.psi_f_Wb = motor["psi_f_Wb"]
        s.Ld_H = motor["Ld_H"]
        s.Lq_H = motor["Lq_H"]
        s.pole_pairs = motor["pole_pairs"]
        s.method = METHODS.index(sc["method"])
        s.feedforward = FEEDFORWARDS.index(sc["feedforward"])
        s.anti_windup = ANTI_WINDUPS.index(sc["anti_windup"])
        if sc["Ka"] is None:
            # section 3.3: Ka = 1/Kp = 1/(J alpha), computed in float32 by the C library
            s.Ka = lib.p2d_speed_Ka_default(s.J_kgm2, s.alpha_radps)
        else:
            s.Ka = sc["Ka"]

        c = cfg.current
        c.Rs_ohm = motor["Rs_ohm"]
        c.Ld_H = s.Ld_H
        c.Lq_H = s.Lq_H
        c.psi_f_Wb = s.psi_f_Wb
        c.tau_i_s = cl["tau_i_s"]
        c.Ts_s = cl["Ts_s"]
        c.method = METHODS.index(cl["method"])
        c.anti_windup = ANTI_WINDUPS.index(cl["anti_windup"])
        c.decouple = cl["decouple"]
        _sensing(cfg, data)

        _estimator(cfg, data)
        self.full_scales = _arithmetic(cfg, data)

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
                sim["log_every"],
                f"large enough for the log to fit in the memory this process may use: {rows} rows"
                f"{self._rate_text()} need {format_bytes(rows * lib.P2D_LOG_COUNT * 8)} (log_every >= {least} "
                "keeps it below "
                f"{format_bytes(LOG_BYTES_MAX // 8)})",
            ) from None
        self._log_ptr = ffi.cast("double *", ffi.from_buffer(self.log))

    def _rate_text(self) -> str:
        """How the rows of a log at the current rate come about, for a message ("" at the speed rate)."""
        if self.data["simulation"]["log_rate"] == "speed":
            return ""
        return (
            f" (simulation.log_rate = 'current': a row every {self.data['simulation']['log_every']} of the "
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

    def _value(self, key: str) -> Any:
        node: Any = self.data
        for part in key.split("."):
            node = node[part]
        return node

    def _raise_config(self, status: int) -> None:
        if status in (lib.P2D_SIM_ERR_SPEED_SENSOR, lib.P2D_SIM_ERR_FIELD_WEAKENING) and self.sim.controller_status:
            ctl = self.sim.controller_status
            field = c_string(lib.p2d_status_param(ctl))
            key = _SENSING_KEYS[field]
            derived = getattr(self.cfg.sensing.field_weakening.config, field, None)
            raise self._blame(key, c_string(lib.p2d_status_range(ctl)), derived)
        if status in (lib.P2D_SIM_ERR_SPEED_CONTROLLER, lib.P2D_SIM_ERR_CURRENT_CONTROLLER, lib.P2D_SIM_ERR_ESTIMATOR):
            ctl = self.sim.controller_status
            field = c_string(lib.p2d_status_param(ctl))
            valid = c_string(lib.p2d_status_range(ctl))
            keys = {
                lib.P2D_SIM_ERR_SPEED_CONTROLLER: _SPEED_KEYS,
                lib.P2D_SIM_ERR_CURRENT_CONTROLLER: _CURRENT_KEYS,
                lib.P2D_SIM_ERR_ESTIMATOR: _ESTIMATOR_KEYS,
            }[status]
            key = keys[field]
            derived = getattr(self.cfg.adapt.config, field, None) if status == lib.P2D_SIM_ERR_ESTIMATOR else None
            if status == lib.P2D_SIM_ERR_SPEED_CONTROLLER and field in self.full_scales:
                # a full scale of the fixed-point controller, in the key's unit (rpm for the speed)
                derived = self.full_scales[field] * (RPM_PER_RADPS if field == "speed_full_scale_radps" else 1.0)
                if field == "speed_full_scale_radps":
                    valid += f" (speed_full_scale_radps = speed_full_scale_rpm pi/30 = {self.full_scales[field]:.6g})"
            value = self._value(key)
            note = float32_note(derived if value is None else value)
            s = self.cfg.speed
            if status == lib.P2D_SIM_ERR_SPEED_CONTROLLER and field == "J_kgm2" and not note:
                # a gain of eq 9 overflowed float32: name the factor farthest from 1
                factors = {"J_kgm2": s.J_kgm2, "alpha_radps": s.alpha_radps, "zeta": 1.0 / s.zeta}
                field = max(factors, key=lambda k: abs(math.log(factors[k])))
                key = _SPEED_KEYS[field]
                Kp, Ki = pi_gains(s.J_kgm2, s.alpha_radps, s.zeta)
                valid = (
                    f"a value that keeps the gains of eq 9 finite in float32 (Kp = J alpha = {Kp:.4g}, "
                    f"Ki = J (alpha / (2 zeta))^2 = {Ki:.4g} with J_kgm2 = {s.J_kgm2:g}, alpha_radps = "
                    f"{s.alpha_radps:g}, zeta = {s.zeta:g})"
                )
            elif status == lib.P2D_SIM_ERR_SPEED_CONTROLLER and field == "Ts_s" and not note:
                # the speed controller's refusal of a sound period: its float32 coefficients overflowed
                valid += (
                    f" (it is: the controller's float32 coefficients overflow with J_kgm2 = {s.J_kgm2:g}, "
                    f"alpha_radps = {s.alpha_radps:g} and i_max_A = {s.i_max_A:g})"
                )
            else:
                valid += note
            if key != "speed_controller.Ka":
                raise self._blame(key, valid, derived)
            sc = self.data["speed_controller"]
            if sc["Ka"] is not None:
                _, Ki = pi_gains(s.J_kgm2, s.alpha_radps, s.zeta)
                valid = (
                    f"finite, >= 0 and, with back_calculation, Ki Ka Ts_s < 2, i.e. Ka < "
                    f"{2.0 / (Ki * s.Ts_s):.6g} (Ki = {Ki:.6g} by eq 9)"
                )
                raise ConfigError(key, sc["Ka"], valid)
            if s.alpha_radps * s.Ts_s / (4.0 * s.zeta**2) >= 2.0 * (1.0 - 1e-6):
                # the default 1/Kp made Ki Ka Ts >= 2: name what the user set
                names = {name: f"speed_controller.{name}" for name in ("alpha_radps", "zeta", "Ts_s", "Ka")}
                raise default_Ka_error(sc["J_kgm2"], sc["alpha_radps"], sc["zeta"], sc["Ts_s"], names)
            raise ConfigError(
                "speed_filter",
                "<table>",
                f"filters through which the back-calculation loop with the default Ka = 1/Kp = {s.Ka:.6g} "
                "(speed_controller.Ka absent) is stable; or give speed_controller.Ka smaller",
            )
        field = c_string(lib.p2d_sim_status_param(status))
        valid = c_string(lib.p2d_sim_status_text(status))
        raise self._blame(_SIM_KEYS[field], valid)

    def _blame(self, key: str, valid: str, derived: float | None = None) -> ConfigError:
        """The ConfigError of ``key``, or, when ``key`` was absent and took its value from another key
        (:data:`_SOURCES`: the defaults the engine derives), of that key: the input the user set.

        ``derived`` is the value the engine derived for a key absent from the data (None in it).
        """
        value = self._value(key)
        source = _SOURCES.get(key)
        if source is not None:
            origin, how = source
            is_default = value is None if key not in _SAME_AS else value == self._value(origin)
            if is_default:
                shown = value if value is not None else derived
                return ConfigError(
                    origin,
                    self._value(origin),
                    f"a value that makes {key} (when not given, {how} = {shown:.6g}) valid: {valid}",
                )
        return ConfigError(key, value, valid)

    def stop_error(self, status: int) -> SimulationError:
        """The SimulationError of the stop ``status`` (a ``P2D_SIM_STOP_*`` code) of this run."""
        sim = self.sim
        reason = c_string(lib.p2d_sim_status_text(status))
        if status == lib.P2D_SIM_STOP_OVERSPEED:
            reason += f": |speed| = {sim.stop_value * RPM_PER_RADPS:.6g} rpm > {sim.stop_bound * RPM_PER_RADPS:.6g} rpm"
            motor, i_max_A = self.data["motor"], self.data["limits"]["i_max_A"]
            T_peak = peak_torque_Nm(i_max_A, motor["pole_pairs"], motor["psi_f_Wb"], motor["Ld_H"], motor["Lq_H"])
            over = [
                (i, e)
                for i, e in enumerate(self.data["load"])
                if e["t_s"] <= sim.t_stop_s and abs(e["torque_Nm"]) > T_peak
            ]
            if over:
                i, e = over[-1]
                reason = (
                    f"the load load.{i}.torque_Nm = {e['torque_Nm']:.6g} Nm is above the peak torque {T_peak:.4g} "
                    f"Nm that limits.i_max_A = {i_max_A:g} A gives: it stalled the drive and turned it backwards "
                    f"({reason})"
                )
        elif status == lib.P2D_SIM_STOP_OVERCURRENT:
            reason += f": ||i_dq|| = {sim.stop_value:.6g} A > {sim.stop_bound:.6g} A"
        return SimulationError(f"simulation of {self.data['name']!r} stopped at t = {sim.t_stop_s:.6g} s: {reason}")


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


def _schedule(
    target: Any, entries: Sequence[Mapping[str, Any]], value_key: str, scale: float
) -> list[npt.NDArray[np.float64]]:
    """Fill the C schedule ``target`` from scenario entries; return the arrays it points into."""
    arrays = [
        np.array([e[k] * (scale if k == value_key else 1.0) for e in entries], dtype=np.float64)
        for k in ("t_s", value_key, "ramp_s")
    ]
    target.n = len(entries)
    if entries:
        target.t_s, target.value, target.ramp_s = (ffi.cast("double *", ffi.from_buffer(a)) for a in arrays)
    return arrays


def _mechanics(cfg: Any, mechanics: Mapping[str, Any], speed_filter: Mapping[str, float]) -> None:
    """Fill the drive train and the speed controller's torque filters of the C configuration ``cfg``."""
    mech = cfg.mechanics
    mech.model = MECHANICS_MODELS.index(mechanics["model"])
    mech.feedback = FEEDBACKS.index(mechanics["feedback"])
    if mechanics["model"] == "two_mass":
        for key in ("J_load_kgm2", "stiffness_Nm_per_rad", "damping_Nms_per_rad", "backlash_rad"):
            setattr(mech, key, mechanics[key])
    for key, value in speed_filter.items():
        setattr(cfg.speed_filter, key, value)


def _faults(cfg: Any, entries: Sequence[Mapping[str, Any]]) -> Any:
    """Fill ``cfg.faults`` from the scenario's ``fault`` entries; return the C array it points to."""
    faults = ffi.new("p2d_fault_t[]", max(1, len(entries)))
    for f, e in zip(faults, entries):
        f.kind = FAULT_KINDS.index(e["kind"])
        f.t_s = e["t_s"]
        f.duration_s = 0.0 if e["duration_s"] is None else e["duration_s"]
        if e["kind"] == "dc_link_sag":
            f.value = e["u_dc_factor"]
        elif e["kind"] == "sensor_spike":
            f.value = e["speed_rpm"] / RPM_PER_RADPS
    cfg.faults = faults
    cfg.n_faults = len(entries)
    return faults


def _estimator(cfg: Any, data: Mapping[str, Any]) -> None:
    """The estimator block of the engine's configuration (``[estimator]``, csrc/sim/adapt.h)."""
    est, sc, motor = data["estimator"], data["speed_controller"], data["motor"]
    a = cfg.adapt
    a.enabled = est["enabled"]
    if not est["enabled"]:
        return
    a.adapt_gains = est["adapt_gains"]
    a.Ka_follows_J = sc["Ka"] is None
    a.adapt_rel_change = est["adapt_rel_change"]
    a.e_quiet_radps = est["adapt_error_rpm"] / RPM_PER_RADPS
    T_peak_Nm = 1.5 * motor["pole_pairs"] * motor["psi_f_Wb"] * data["limits"]["i_max_A"]
    J0 = est["J0_kgm2"]
    derived = {
        "J_min_kgm2": J0 / 10.0,
        "J_max_kgm2": 10.0 * J0,
        "B_max_Nms": T_peak_Nm / 100.0,
        "T_load_max_Nm": T_peak_Nm,
        "sigma_T_Nm": 0.01 * T_peak_Nm,
        "load_memory_s": 1.0 / sc["alpha_radps"],
        "w_f_radps": 0.2 / sc["Ts_s"],
    }
    c = a.config
    c.Ts_s = sc["Ts_s"]
    c.J0_kgm2 = J0
    for key, value in derived.items():
        setattr(c, key, value if est[key] is None else est[key])
    c.J_memory_s = est["J_memory_s"]
    c.J_rel_sd_max = est["J_rel_sd_max"]
    c.speed_is_period_mean = est["speed_is_period_mean"]


def _sensing(cfg: Any, data: Mapping[str, Any]) -> None:
    """Fill the speed sensor, current measurement and field weakening of ``cfg`` (csrc/sim/sensing.h)."""
    ss, cm, fw = data["speed_sensor"], data["current_measurement"], data["field_weakening"]
    sensor = cfg.sensing.speed_sensor
    sensor.model = SPEED_SENSOR_MODELS.index(ss["model"])
    sensor.encoder.counts_per_rev = ss["counts_per_rev"]
    sensor.encoder.counter_bits = ss["counter_bits"]
    sensor.encoder.estimator = ESTIMATORS.index(ss["estimator"])
    sensor.encoder.bandwidth_radps = 0.0 if ss["bandwidth_radps"] is None else ss["bandwidth_radps"]
    sensor.encoder.lowpass_radps = ss["lowpass_radps"]
    sensor.delay_s = ss["delay_s"]
    sensor.noise_rms_radps = ss["noise_rpm_rms"] / RPM_PER_RADPS
    sensor.seed = ss["seed"]
    meas = cfg.sensing.current_sensor
    for key in ("gain_error_a", "gain_error_b", "offset_a_A", "offset_b_A", "seed"):
        setattr(meas, key, cm[key])
    meas.noise_rms_A = cm["noise_A_rms"]
    cfg.sensing.field_weakening.enabled = fw["enabled"]
    if fw["enabled"]:
        reg = cfg.sensing.field_weakening.config
        Ts_s = data["speed_controller"]["Ts_s"]
        reg.Kp_A_per_V = fw["Kp_A_per_V"]
        reg.Ki_A_per_Vs = fw["Ki_A_per_Vs"]
        # absent: Ki Ka Ts = 1, the back-calculation's own time constant one sample
        reg.Ka_V_per_A = 1.0 / (fw["Ki_A_per_Vs"] * Ts_s) if fw["Ka_V_per_A"] is None else fw["Ka_V_per_A"]
        reg.Ts_s = Ts_s
        reg.voltage_ratio = fw["voltage_ratio"]
        reg.id_min_A = -data["limits"]["i_max_A"] if fw["id_min_A"] is None else fw["id_min_A"]
        reg.method = METHODS.index("tustin")
        reg.anti_windup = ANTI_WINDUPS.index("back_calculation")


#: Default speed full scale of the fixed-point controllers in no-load speeds: the engine's overspeed bound
#: (``P2D_SIM_OVERSPEED_FACTOR``), so that every speed a run reaches is within the input's range.
FULL_SCALE_NO_LOAD_SPEEDS = 2.0
#: Margin of the default torque full scale over the smallest that holds the states [-].
FULL_SCALE_MARGIN = 1.25


def _float32_up(x: float) -> float:
    """The float32 number nearest ``x`` at or above it: a full scale that still holds ``x`` once stored."""
    x32 = np.float32(x)
    return float(x32) if float(x32) >= x else float(np.nextafter(x32, np.float32(np.inf)))


def _arithmetic(cfg: Any, data: Tree) -> dict[str, float]:
    """Fill the arithmetic of the speed controller and, for Q15 or Q31, its full scales (given or derived,
    see :data:`~pmsm2dof.sim.scenario.SCHEMA`); return the full scales used by C field name ({} for float32).

    The derived torque full scale keeps within the two full scales the format holds (speed_fixed.h)
    the integrator state ``x = x_i + Fr(0) r`` up to ``T_max + |Fr(0)| r_max``, the feedforward
    transient ``y`` up to ``|b_dr| dr_max`` after the largest reference step ``dr_max``, and the command
    ``u`` at that step, ``T_max + (b_e0 + |Fr(0) + b_dr|) dr_max`` (so that the back calculation sees
    the ``u* = u_sat - u`` the float32 controller sees); the gains are the C controller's
    (``p2d_speed_q15_gains``).
    """
    sc, motor = data["speed_controller"], data["motor"]
    cfg.arithmetic = ARITHMETICS.index(sc["arithmetic"])
    if sc["arithmetic"] == "float32":
        return {}
    s = cfg.speed
    kt = 1.5 * s.pole_pairs * s.psi_f_Wb
    T_max = kt * s.i_max_A
    W_fs = (
        FULL_SCALE_NO_LOAD_SPEEDS
        * no_load_speed_radps(data["limits"]["u_dc_V"], motor["pole_pairs"], motor["psi_f_Wb"])
        if sc["speed_full_scale_rpm"] is None
        else sc["speed_full_scale_rpm"] / RPM_PER_RADPS
    )
    cfg.speed_full_scale_radps = W_fs
    T_fs = sc["torque_full_scale_Nm"]
    if T_fs is None:
        T_fs = T_max
        # the feedforward's gains in physical units, from the C controller at provisional full scales
        cfg.torque_full_scale_Nm = _float32_up(T_max)
        cfg.current_full_scale_A = _float32_up(s.i_max_A)
        fixed = ffi.new(
            "p2d_speed_fixed_config_t *",
            [cfg.speed, cfg.speed_full_scale_radps, cfg.torque_full_scale_Nm, cfg.current_full_scale_A],
        )
        gains = ffi.new("p2d_speed_fixed_gains_t *")
        if getattr(lib, f"p2d_speed_{sc['arithmetic']}_gains")(fixed, gains) == lib.P2D_OK:
            per_unit = cfg.torque_full_scale_Nm / cfg.speed_full_scale_radps
            Fr0, b_dr = abs(gains.ff_Fr0) * per_unit, abs(gains.ff_b_dr) * per_unit
            # u at a reference step dr from rest: b_e0 dr + x + (Fr0 + b_dr) dr (the derivative kick of the
            # full feedforward left out: it saturates the command anyway)
            u_per_dr = (gains.b_e0 + abs(gains.ff_Fr0 + gains.ff_b_dr)) * per_unit
            # the references in the order the controller sees them: w_m0, 0 until the first entry, the entries
            w_m0 = data["simulation"]["speed0_rpm"] / RPM_PER_RADPS
            refs = [w_m0] + ([0.0] if data["reference"][0]["t_s"] > 0.0 else [])
            refs += [e["speed_rpm"] / RPM_PER_RADPS for e in data["reference"]]
            r_max = max(abs(r) for r in refs)
            dr_max = max(abs(b - a) for a, b in zip(refs, refs[1:]))
            held = max(T_max + Fr0 * r_max, b_dr * dr_max, T_max + u_per_dr * dr_max) / 2.0
            T_fs = max(T_max, FULL_SCALE_MARGIN * held)
        cfg.torque_full_scale_Nm = _float32_up(T_fs)
    else:
        cfg.torque_full_scale_Nm = T_fs
    I_fs = sc["current_full_scale_A"]
    cfg.current_full_scale_A = _float32_up(max(s.i_max_A, T_fs / kt)) if I_fs is None else I_fs
    return {name: float(getattr(cfg, name)) for name in FULL_SCALES}


#: The full scales of the fixed-point speed controller in the engine's configuration (``p2d_sim_config_t``).
FULL_SCALES = ("speed_full_scale_radps", "torque_full_scale_Nm", "current_full_scale_A")
