"""The commissioning routine on the MCU's instruction set: the same float32 bits on QEMU as on the host.

The routine sums thousands of samples, divides and takes square roots, and its
phase changes hang on comparisons of those results with thresholds: a single
different rounding on the MCU could end a run elsewhere. The input sequences
(measured currents and DC link of every sample) are recorded here from
closed-loop runs of the host build (``pmsm2dof._core``) against a small motor
model, with current noise and a few NaN and infinite samples; the Cortex-M4F
build replays them on QEMU (``-M mps2-an386``, ``csrc/target/
target_commission_vectors.c``) and every output word of every sample, and the
routine's results at the end, must equal the host's to the bit. The routine
uses +, -, *, /, sqrt and fmaf only (no libm approximations), which IEEE 754
rounds the same way on both; both builds keep a*b+c unfused
(``-ffp-contract=off``).

Without the cross toolchain, cmake or qemu-system-arm the test is skipped with the reason.
"""

import math
import subprocess

import numpy as np
import pytest
from test_target_qemu import (
    BUILD_TIMEOUT_S,
    CSRC,
    QEMU,
    QEMU_TIMEOUT_S,
    TOOLCHAIN,
    c_value,
    needs_cross,
    needs_qemu,
    run,
    word,
)

from pmsm2dof._core import ffi, lib

#: Slow (builds, emulators, fuzzing, browsers or whole reproductions): run by the full suite.
pytestmark = [pytest.mark.slow, needs_cross, needs_qemu]

SAMPLE_FIELDS = ("ud_V", "uq_V", "theta_e_rad", "w_e_radps", "id_ref_A", "iq_ref_A", "phase", "fault")
END_FIELDS = (
    "phase",
    "failed_phase",
    "reason",
    "fault_count",
    "L_probe_H",
    "Rs_ohm",
    "u_err_V",
    "Ld_H",
    "Lq_H",
    "psi_f_Wb",
    "rs_spread",
    "asymmetry",
    "coherence",
    "psi_spread",
    "slip",
)


def servo_config(**changes):
    """A commissioning of a small servo that ends within 17200 samples of 100 us."""
    cfg = dict(
        Ts_s=1e-4,
        i_test_A=2.0,
        i_spin_A=1.5,
        i_trip_A=4.0,
        tau_i_s=1e-3,
        t_align_s=0.05,
        t_level_s=0.4,
        t_inductance_s=0.0128,
        t_ramp_s=0.3,
        t_spin_s=0.2,
        w_e_spin_radps=100.0,
        voltage_delay_samples=0,
    )
    cfg.update(changes)
    return {k: v if isinstance(v, int) else float(np.float32(v)) for k, v in cfg.items()}


# (configuration, motor, samples, what the run must end in)
CASES = [
    # a salient servo, noise, two NaN and an infinite sample: DONE
    (servo_config(), dict(Rs=0.8, Ld=4e-3, Lq=8e-3, psi_f=0.05, J=2e-4, B=2e-4, sign=1.0, delay=0), 17200, "done"),
    # a surface motor behind one period of delay: DONE
    (
        servo_config(voltage_delay_samples=1),
        dict(Rs=0.5, Ld=6e-3, Lq=6e-3, psi_f=0.08, J=4e-4, B=4e-4, sign=1.0, delay=1),
        17200,
        "done",
    ),
    # current sensing of the wrong sign: the trip in ALIGN
    (servo_config(), dict(Rs=0.8, Ld=4e-3, Lq=8e-3, psi_f=0.05, J=2e-4, B=1e-5, sign=-1.0, delay=0), 1500, "failed"),
    # a configuration that init rejects (i_trip below 1.5 i_test)
    (servo_config(i_trip_A=2.5), None, 0, None),
]


def record_inputs(cfg, motor, n, rng):
    """(n, 3) float32 inputs (id, iq, u_dc) of a closed-loop run of the host routine against the motor.

    Forward Euler, 8 steps per sample, of the dq model in the rotor frame with the rotor's angle and
    mechanics; the stationary-frame voltage is held over each period, after the motor's delay.
    """
    c = ffi.new("p2d_commission_t *")
    assert lib.p2d_commission_init(c, ffi.new("p2d_commission_config_t *", cfg)) == 0
    out = ffi.new("p2d_commission_output_t *")
    m, p, u_dc, h = motor, 4, 48.0, cfg["Ts_s"] / 8
    i_d = i_q = w_m = 0.0
    theta = 0.7
    held = (0.0, 0.0)
    rows = np.empty((n, 3), dtype=np.float32)
    for k in range(n):
        th = c.theta_e_rad
        ia, ib = math.cos(theta) * i_d - math.sin(theta) * i_q, math.sin(theta) * i_d + math.cos(theta) * i_q
        d = m["sign"] * (math.cos(th) * ia + math.sin(th) * ib) + 0.01 * rng.standard_normal()
        q = m["sign"] * (-math.sin(th) * ia + math.cos(th) * ib) + 0.01 * rng.standard_normal()
        rows[k] = (d, q, u_dc)
        if k in (1234, 4321):
            rows[k, 0] = np.nan  # a lost current measurement
        if k == 3000:
            rows[k, 2] = np.inf  # a wrong DC-link reading
        lib.p2d_commission_step(c, *rows[k].tolist(), out)
        a = out.theta_e_rad
        u = (math.cos(a) * out.ud_V - math.sin(a) * out.uq_V, math.sin(a) * out.ud_V + math.cos(a) * out.uq_V)
        u, held = (held, u) if m["delay"] else (u, held)
        for _ in range(8):
            cr, sr = math.cos(theta), math.sin(theta)
            ud, uq = cr * u[0] + sr * u[1], -sr * u[0] + cr * u[1]
            w_e = p * w_m
            torque = 1.5 * p * (m["psi_f"] * i_q + (m["Ld"] - m["Lq"]) * i_d * i_q)
            i_d, i_q = (
                i_d + h / m["Ld"] * (ud - m["Rs"] * i_d + w_e * m["Lq"] * i_q),
                i_q + h / m["Lq"] * (uq - m["Rs"] * i_q - w_e * (m["Ld"] * i_d + m["psi_f"])),
            )
            w_m += h / m["J"] * (torque - m["B"] * w_m)
            theta += h * w_e
    return rows


def vectors_header(cases, inputs):
    """Text of p2d_commission_vectors.h (see csrc/target/target_commission_vectors.c)."""
    configs = ",\n".join(
        "{"
        + ", ".join(
            f".{k} = {c_value(v)}u" if k == "voltage_delay_samples" else f".{k} = {c_value(v)}" for k, v in cfg.items()
        )
        + "}"
        for cfg, *_ in cases
    )
    words = np.concatenate([x.reshape(-1) for x in inputs] + [np.zeros(3, np.float32)]).view(np.uint32)
    return "\n".join(
        [
            "/* written by tests/test_target_qemu_commission.py */",
            f"#define P2D_CVEC_CASES {len(cases)}u",
            "static const p2d_commission_config_t p2d_cvec_config[P2D_CVEC_CASES] = {",
            configs,
            "};",
            "static const uint32_t p2d_cvec_samples[P2D_CVEC_CASES] = {"
            + ", ".join(f"{len(x)}u" for x in inputs)
            + "};",
            "static const uint32_t p2d_cvec_input[] = {",
            ",\n".join(f"0x{w:08x}u" for w in words),
            "};",
            "",
        ]
    )


def host_run(cfg, x):
    """(status, sample rows, end row) of the host build on the inputs x, as the target prints them."""
    c = ffi.new("p2d_commission_t *")
    status = lib.p2d_commission_init(c, ffi.new("p2d_commission_config_t *", cfg))
    rows = []
    if status != 0:
        return status, rows, None
    for d, q, u_dc in x.tolist():
        out = ffi.new("p2d_commission_output_t *")
        lib.p2d_commission_step(c, d, q, u_dc, out)
        rows.append([word(out[0], f) for f in SAMPLE_FIELDS])
    return status, rows, [word(c[0], f) for f in END_FIELDS]


def parse(text):
    status, rows, ends = {}, {}, {}
    for line in text.splitlines():
        p = line.split()
        if p and p[0] == "I":
            status[int(p[1], 16)] = int(p[2], 16)
        elif p and p[0] == "M":
            rows[int(p[1], 16), int(p[2], 16)] = [int(w, 16) for w in p[3:]]
        elif p and p[0] == "E":
            ends[int(p[1], 16)] = [int(w, 16) for w in p[2:]]
    return status, rows, ends


def test_commissioning_on_qemu_equals_host_to_the_bit(tmp_path):
    rng = np.random.default_rng(20260301)
    inputs = [
        record_inputs(cfg, motor, n, rng) if motor else np.zeros((0, 3), np.float32) for cfg, motor, n, _ in CASES
    ]
    (tmp_path / "p2d_commission_vectors.h").write_text(vectors_header(CASES, inputs))
    build = tmp_path / "build"
    run(
        [
            "cmake",
            "-S",
            CSRC,
            "-B",
            build,
            f"-DCMAKE_TOOLCHAIN_FILE={TOOLCHAIN}",
            f"-DP2D_COMMISSION_VECTORS_DIR={tmp_path}",
        ]
    )
    run(["cmake", "--build", build, "-j2", "--target", "p2d_commission_vectors"], timeout=BUILD_TIMEOUT_S)
    done = subprocess.run(
        [*QEMU, "-kernel", str(build / "target" / "p2d_commission_vectors")],
        capture_output=True,
        text=True,
        timeout=QEMU_TIMEOUT_S,
        stdin=subprocess.DEVNULL,
    )
    # semihosting output arrives on stderr
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stderr.splitlines()[-1] == "END"
    target_status, target_rows, target_ends = parse(done.stderr)

    phase_of = {"done": lib.P2D_PHASE_DONE, "failed": lib.P2D_PHASE_FAILED}
    phases_seen = set()
    for case, ((cfg, _, n, ends_in), x) in enumerate(zip(CASES, inputs)):
        status, rows, end = host_run(cfg, x)
        assert target_status[case] == status, (case, status, target_status[case])
        if ends_in is None:
            assert status == lib.P2D_ERR_I_TRIP
            continue
        assert status == 0
        mismatches = [
            f"case {case} sample {k} {name}: target {t:08x}, host {h:08x}"
            for k, row in enumerate(rows)
            for name, h, t in zip(SAMPLE_FIELDS, row, target_rows[case, k])
            if h != t
        ]
        mismatches += [
            f"case {case} end {name}: target {t:08x}, host {h:08x}"
            for name, h, t in zip(END_FIELDS, end, target_ends[case])
            if h != t
        ]
        assert not mismatches, (
            f"{len(mismatches)} words differ (is pmsm2dof._core older than csrc/src? rebuild "
            "it with pip install -e .):\n" + "\n".join(mismatches[:20])
        )
        assert len(rows) == n and all((case, k) in target_rows for k in range(n))
        # the runs went where they were meant to: through every phase to DONE, or to the trip
        assert end[0] == phase_of[ends_in], (case, end)
        phases_seen |= {row[SAMPLE_FIELDS.index("phase")] for row in rows}
        assert sum(row[SAMPLE_FIELDS.index("fault")] for row in rows) == 3 or ends_in == "failed"
    assert phases_seen == set(range(lib.P2D_PHASE_DONE + 1)) | {lib.P2D_PHASE_FAILED}, phases_seen
