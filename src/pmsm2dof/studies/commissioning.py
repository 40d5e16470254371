"""Accuracy of the commissioning routine over the paper's drive, a salient servo and random machines.

:func:`random_machines` draws seeded machines over the range of small industrial PMSMs and
servos, each with the drive a commissioning engineer would pair with it; :func:`accuracy_study`
commissions each on an ideal drive and on a real one (dead-time error, current noise, one period
of computation delay) with :func:`pmsm2dof.sim.commission.commission`, and tabulates identified
against true values. The routine promises an estimate only when its self-checks passed: every run
ends DONE within :data:`~pmsm2dof.sim.commission.TARGETS` or FAILED with a reason.
"""

import math
from dataclasses import dataclass

import numpy as np

from ..sim.commission import ESTIMATES, TARGETS, Commissioning, commission
from ..sim.scenario import Scenario, load_scenario

__all__ = ["SERVO", "AccuracyRow", "accuracy_study", "random_machines", "real_drive", "servo_scenario"]

#: The salient servo of the commissioning guide (docs/your-motor.md, examples/commissioning/servo-salient.toml):
#: Rs = 0.8 ohm, Ld = 4 mH, Lq = 8 mH, psi_f = 0.05 Wb, p = 4, J = 2e-4 kg m^2, 48 V, 5 A.
SERVO = {
    "name": "salient servo",
    "motor.pole_pairs": 4,
    "motor.Rs_ohm": 0.8,
    "motor.Ld_H": 0.004,
    "motor.Lq_H": 0.008,
    "motor.psi_f_Wb": 0.05,
    "motor.J_kgm2": 2e-4,
    "motor.B_Nms": 1e-5,
    "limits.i_max_A": 5.0,
    "limits.u_dc_V": 48.0,
}


def servo_scenario() -> Scenario:
    """The paper's scenario (paper-condition-2) with the salient servo of :data:`SERVO` as its drive."""
    return load_scenario("paper-condition-2").with_overrides(SERVO)


def real_drive(scenario: Scenario, dead_time_share: float = 0.01, noise_share: float = 0.01) -> Scenario:
    """The scenario on a real inverter: a dead-time error of ``dead_time_share u_dc`` per phase,
    current noise of ``noise_share i_test_A`` per phase, one period of computation delay, and four
    RK4 steps per current period (the dead-time error switches within a period)."""
    from ..sim.commission import commissioning_config

    return scenario.with_overrides(
        {
            "inverter.computation_delay": True,
            "commissioning.dead_time_V": dead_time_share * scenario.limits.u_dc_V,
            "commissioning.noise_A": noise_share * commissioning_config(scenario)["i_test_A"],
            "simulation.dt_s": scenario.current_loop.Ts_s / 4,
        }
    )


def random_machines(n: int, seed: int) -> list[Scenario]:
    """``n`` seeded random machines on the servo scenario's structure.

    Log-uniform: Rs in [0.05, 5] ohm, Ld in [0.5, 20] mH, psi_f in [0.01, 0.3] Wb, J in
    [1e-5, 1e-2] kg m^2; Lq / Ld uniform in [1, 2.5]; pole pairs 2 to 5. The drive: 48 V below
    psi_f = 0.05 Wb, else 320 V; i_max_A log-uniform in [2, 20] A, at most what drops 20 % of
    u_dc / sqrt(3) across Rs; viscous friction giving a mechanical time constant J / B of 10 s.
    """
    rng = np.random.default_rng(seed)
    base = servo_scenario()
    machines = []
    for i in range(n):

        def log_uniform(low: float, high: float) -> float:
            return float(math.exp(rng.uniform(math.log(low), math.log(high))))

        Rs, Ld, psi_f, J = (
            log_uniform(0.05, 5.0),
            log_uniform(5e-4, 2e-2),
            log_uniform(0.01, 0.3),
            log_uniform(1e-5, 1e-2),
        )
        Lq = Ld * float(rng.uniform(1.0, 2.5))
        p = int(rng.integers(2, 6))
        u_dc = 48.0 if psi_f < 0.05 else 320.0
        i_max = min(log_uniform(2.0, 20.0), 0.2 * u_dc / math.sqrt(3.0) / Rs)
        machines.append(
            base.with_overrides(
                {
                    "name": f"random machine {i} (seed {seed})",
                    "motor.pole_pairs": p,
                    "motor.Rs_ohm": Rs,
                    "motor.Ld_H": Ld,
                    "motor.Lq_H": Lq,
                    "motor.psi_f_Wb": psi_f,
                    "motor.J_kgm2": J,
                    "motor.B_Nms": J / 10.0,
                    "limits.u_dc_V": u_dc,
                    "limits.i_max_A": i_max,
                }
            )
        )
    return machines


@dataclass(frozen=True)
class AccuracyRow:
    """One commissioning run of the study: the machine, the drive, the outcome."""

    machine: str
    drive: str
    result: Commissioning

    def as_dict(self) -> dict[str, object]:
        r = self.result
        return {
            "machine": self.machine,
            "drive": self.drive,
            "phase": r.phase,
            "failed_phase": r.failed_phase,
            "reason": r.reason,
            "within_targets": r.within_targets,
            **{f"{k}_error": (e if math.isfinite(e) else None) for k, e in r.errors.items()},
            "time_s": sum(r.phase_time_s.values()),
        }


def accuracy_study(n_random: int = 100, seed: int = 20) -> list[AccuracyRow]:
    """Commission the paper's drive, the servo and ``n_random`` random machines, ideal and real drive."""
    named = [("paper drive", load_scenario("paper-condition-2")), ("salient servo", servo_scenario())]
    named += [(s.name, s) for s in random_machines(n_random, seed)]
    rows = []
    for name, scenario in named:
        rows.append(AccuracyRow(name, "ideal", commission(scenario)))
        rows.append(AccuracyRow(name, "real", commission(real_drive(scenario))))
    return rows


def summary_table(rows: list[AccuracyRow]) -> str:
    """Markdown: the named machines one per line, the random ones summarised per drive."""
    lines = [
        "| Machine | Drive | Outcome | Rs | Ld | Lq | psi_f | Simulated time |",
        "|---|---|---|---|---|---|---|---|",
    ]

    def pct(x: float) -> str:
        return f"{x * 100:+.2f} %" if math.isfinite(x) else "-"

    for row in rows:
        if row.machine.startswith("random machine"):
            continue
        r = row.result
        outcome = r.phase if r.phase == "done" else f"failed in {r.failed_phase}: {r.reason}"
        errors = " | ".join(pct(r.errors[k]) for k in ESTIMATES)
        lines.append(f"| {row.machine} | {row.drive} | {outcome} | {errors} | {sum(r.phase_time_s.values()):.3g} s |")
    for drive in ("ideal", "real"):
        random_rows = [r for r in rows if r.machine.startswith("random machine") and r.drive == drive]
        if not random_rows:
            continue
        done = [r.result for r in random_rows if r.result.phase == "done"]
        worst = " | ".join(f"max {max(abs(r.errors[k]) for r in done) * 100:.2f} %" if done else "-" for k in ESTIMATES)
        reasons: dict[str, int] = {}
        for random_row in random_rows:
            failed_run = random_row.result
            if failed_run.phase != "done":
                key = f"{failed_run.failed_phase}: {failed_run.reason}"
                reasons[key] = reasons.get(key, 0) + 1
        failed = "; ".join(f"{n} {k}" for k, n in sorted(reasons.items()))
        within = sum(r.within_targets for r in done)
        outcome = f"{len(done)} done ({within} within targets)" + (f", failed: {failed}" if failed else "")
        lines.append(f"| {len(random_rows)} random machines | {drive} | {outcome} | {worst} | |")
    lines.append("")
    lines.append(
        "Targets: " + ", ".join(f"{k} {v * 100:g} %" for k, v in TARGETS.items()) + " (|identified / true - 1|)."
    )
    return "\n".join(lines)
