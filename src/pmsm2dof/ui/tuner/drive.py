"""The tuner's drive mode: the control values written to a drive, its runs captured beside their digital twin.

``pmsm2dof tune SCENARIO --link URL --a2l FILE`` serves the tuner with a
:class:`~pmsm2dof.studies.bench.DriveSession` on the drive: the page arms it, and then every
change of a control is validated as the tuner validates it (:meth:`Tuner.scenario
<pmsm2dof.ui.tuner.experiment.Tuner.scenario>`, then the C controllers' init) and written to the
drive (:meth:`DriveSession.write <pmsm2dof.studies.bench.DriveSession.write>`); "Run on the
drive" plays the experiment's reference and load on it and captures every speed sample of the
firmware's own signals, so that any drive with them runs it (:meth:`DriveSession.run
<pmsm2dof.studies.bench.DriveSession.run>`). The twin is the engine's simulation of the same
control values at every speed sample, its speed as the drive's sensor reads it
(:func:`pmsm2dof.studies.drive.as_measured`); the page draws both, their difference, and the
metrics of both (:func:`pmsm2dof.studies.loopcheck.measure`).
"""

import time
from collections.abc import Mapping
from typing import Any

import numpy as np

from ...sim.simulate import Simulation
from ...studies.bench import DriveSession
from ...studies.drive import as_measured
from ...studies.firmware import compare
from ...studies.loopcheck import measure
from .experiment import Tuner, _label, _metric_rows, minmax_indices

#: Signals of a run the page draws for the drive and the twin: (Result attribute, label, unit).
RUN_SIGNALS = (("speed_ref_rpm", "speed reference", "rpm"), ("speed_rpm", "speed", "rpm"), ("iq_A", "iq", "A"))


def _decimated(t: np.ndarray, ys: Mapping[str, np.ndarray]) -> dict[str, Any]:
    """The signals ``ys`` at the samples min-max decimation keeps of any of them (one time axis)."""
    keep = np.unique(np.concatenate([minmax_indices(y) for y in ys.values()]))
    return {"t": t[keep].tolist(), **{name: np.asarray(y)[keep].tolist() for name, y in ys.items()}}


class DriveMode:
    """The tuner's computations in drive mode: writes and runs on the drive, the twin beside them.

    Parameters
    ----------
    tuner : Tuner
        The tuner of the scenario the drive was built for.
    session : DriveSession
        The session on the drive.
    """

    def __init__(self, tuner: Tuner, session: DriveSession) -> None:
        self.tuner = tuner
        self.session = session

    def describe(self) -> dict[str, Any]:
        """What the page shows of the drive before anything happens: its link, and the heartbeat it must send."""
        return {
            "url": self.session.link.url,
            "virtual": self.session.virtual,
            "heartbeat_timeout_s": self.session.heartbeat_timeout_s,
        }

    def write(self, values: Mapping[str, Any], owner: Any) -> dict[str, Any]:
        """Validate the control values and write their speed controller to the drive; what it reads back."""
        scenario = self.tuner.scenario(values)
        return {"config": self.session.write(scenario, owner)}

    def run(self, values: Mapping[str, Any], owner: Any) -> dict[str, Any]:
        """Run the experiment of the control values on the drive and in the twin; what the page draws.

        Keys: ``drive`` and ``twin`` (decimated ``t`` and the :data:`RUN_SIGNALS`), ``difference``
        (drive minus twin of ``speed_rpm`` and ``iq_A`` at every sample, decimated),
        ``comparison`` (:func:`pmsm2dof.studies.firmware.compare`: the largest differences against
        the step), ``metrics`` (rows ``{key, group, label, unit, twin, drive, reason}``), ``config`` (the
        drive's speed controller read back after the run), ``capture`` (how the run was captured:
        :attr:`RunPlan.why <pmsm2dof.studies.drive.RunPlan>`), ``samples``, ``label``, ``drive_s`` and
        ``twin_s`` (wall times). The speeds are readings: the drive's, and the twin's sensor's.
        """
        scenario = self.tuner.scenario(values)
        self.tuner.logged(scenario)  # the bound of the twin's work, before anything runs
        exact = scenario.with_overrides({"simulation.log_every": 1})
        start = time.perf_counter()
        drive = self.session.run(exact, owner)
        drive_s = time.perf_counter() - start
        start = time.perf_counter()
        sim = Simulation(exact)
        sim.advance(sim.n_samples)
        twin = as_measured(sim.result(exact, time.perf_counter() - start))
        twin_s = time.perf_counter() - start
        t = np.asarray(twin.t_s)
        # the same schedules: the same events, so the same rows (a figure the drive's run lacks is None)
        drive_rows = {r["key"]: r for r in _metric_rows(measure(drive))}
        metrics = [
            {k: r[k] for k in ("key", "group", "label", "unit", "reason")}
            | {"twin": r["value"], "drive": drive_rows[r["key"]]["value"] if r["key"] in drive_rows else None}
            for r in _metric_rows(measure(twin))
        ]
        comparison = compare(drive, twin)
        return {
            "label": _label(exact),
            "samples": len(t),
            "drive": _decimated(t, {name: np.asarray(getattr(drive, name)) for name, _, _ in RUN_SIGNALS}),
            "twin": _decimated(t, {name: np.asarray(getattr(twin, name)) for name, _, _ in RUN_SIGNALS}),
            "difference": _decimated(
                t,
                {
                    "speed_rpm": np.asarray(drive.speed_rpm) - np.asarray(twin.speed_rpm),
                    "iq_A": np.asarray(drive.iq_A) - np.asarray(twin.iq_A),
                },
            ),
            "comparison": {k: comparison[k] for k in ("agreement", "speed", "currents", "agrees")},
            "metrics": metrics,
            "config": self.session.read_speed_config(),
            "capture": self.session.last_plan.why,
            "drive_s": drive_s,
            "twin_s": twin_s,
        }
