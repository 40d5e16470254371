"""The controllers on the MCU's instruction set: Cortex-M4F cross build, firmware example, QEMU runs.

- The static library cross-builds with the toolchain file and carries the
  Cortex-M4F hard-float build attributes.
- The firmware example (examples/firmware) builds with the headers that
  ``pmsm2dof header`` writes during the build (from the preset paper-experiment-1),
  links for the MPS2 AN386 memory map, and on QEMU its 10 kHz interrupt runs the
  current loop every time and the speed loop every 10th time (the porting stub;
  tests/test_firmware.py runs the virtual board closed loop).
- Golden vectors: input sequences generated here run through the speed and the
  current controller, for every method, feedforward form and anti-windup mode,
  the speed controller's field-weakening entry, the encoder speed estimators,
  the field weakening and the inertia estimator (sampled and period-mean speeds,
  memories from short to long), on QEMU (``-M mps2-an386``, a Cortex-M4F) and on the host through
  ``pmsm2dof._core`` (the simulation engine). Every float32 output and state
  word must be equal to the bit. Both builds keep a*b+c unfused
  (``-ffp-contract=off``; the x86-64 host has no FMA at the default ISA level),
  and IEEE 754 makes +, -, *, / and sqrt correctly rounded on both. The one
  allowed difference is the payload of a NaN (an invalid operation gives the
  default NaN, 0x7fc00000 on Arm and 0xffc00000 on x86): NaN must match NaN;
  commands and states, which the non-finite policy keeps finite, must match
  to the bit everywhere.

Without the cross toolchain or cmake the build tests are skipped, without
qemu-system-arm the QEMU tests are skipped, each with the reason.
"""

import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from pmsm2dof.core.bindings import ffi, lib

#: Slow (builds, emulators, fuzzing, browsers or whole reproductions): run by the full suite.
pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[1]
CSRC = ROOT / "csrc"
TOOLCHAIN = CSRC / "cmake" / "arm-none-eabi-cortex-m4f.cmake"
FIRMWARE = ROOT / "examples" / "firmware"
QEMU = ["qemu-system-arm", "-M", "mps2-an386", "-nographic", "-semihosting-config", "enable=on,target=native"]
QEMU_TIMEOUT_S = 120
BUILD_TIMEOUT_S = 600

_MISSING = [t for t in ("cmake", "arm-none-eabi-gcc") if shutil.which(t) is None]
needs_cross = pytest.mark.skipif(
    bool(_MISSING),
    reason=f"{', '.join(_MISSING)} not installed (Debian: cmake gcc-arm-none-eabi "
    "libnewlib-arm-none-eabi; scripts/install.sh installs them)",
)
needs_qemu = pytest.mark.skipif(
    shutil.which("qemu-system-arm") is None,
    reason="qemu-system-arm not installed (Debian: qemu-system-arm; scripts/install.sh installs it)",
)

SAMPLES = 120
METHOD, FEEDFORWARD, ANTI_WINDUP = 3, 4, 3  # number of enumerators of each
SPEED_FIELDS = (
    "w_ref_radps",
    "e_radps",
    "T_ff_Nm",
    "y_ff_Nm",
    "T_unsat_Nm",
    "T_ref_Nm",
    "id_ref_A",
    "iq_ref_A",
    "saturated",
    "fault",
    "x_Nm",
    "r_prev_radps",
    "y_ff_prev_Nm",
    "fault_count",
)
CURRENT_FIELDS = (
    "ed_A",
    "eq_A",
    "ud_unsat_V",
    "uq_unsat_V",
    "ud_ref_V",
    "uq_ref_V",
    "saturated",
    "fault",
    "x_d_V",
    "x_q_V",
    "fault_count",
)
# words that the non-finite policy keeps finite: they must match to the bit, never only as NaN
SPEED_EXACT = {
    "T_ref_Nm",
    "id_ref_A",
    "iq_ref_A",
    "saturated",
    "fault",
    "x_Nm",
    "r_prev_radps",
    "y_ff_prev_Nm",
    "fault_count",
}
CURRENT_EXACT = {"ud_ref_V", "uq_ref_V", "saturated", "fault", "x_d_V", "x_q_V", "fault_count"}
ENCODER_FIELDS = (
    "dn_counts",
    "w_raw_radps",
    "w_m_radps",
    "fault",
    "count_prev",
    "theta_err_counts",
    "v_pll_counts",
    "w_lowpass_radps",
    "fault_count",
)
FW_FIELDS = ("u_ref_V", "e_V", "id_unsat_A", "id_ref_A", "active", "at_id_min", "fault", "x_A", "fault_count")
# the encoder reads integers only: every word is finite and must match; the field weakening holds its state finite
ENCODER_EXACT = set(ENCODER_FIELDS)
FW_EXACT = {"id_ref_A", "active", "at_id_min", "fault", "x_A", "fault_count"}
INERTIA_OUTPUT_FIELDS = (
    "J_kgm2",
    "J_sd_kgm2",
    "B_Nms",
    "T_load_Nm",
    "residual_Nm",
    "residual_sd_Nm",
    "J_valid",
    "updated",
    "fault",
)
INERTIA_STATE_FIELDS = (
    "T_load_Nm",
    "J_kgm2",
    "B_Nms",
    "U_LJ_per_s2",
    "U_LB_per_s",
    "U_JB_s",
    "D_L_N2m2",
    "D_J_kg2m4",
    "D_B_N2m2s2",
    "wF_radps",
    "w0_radps",
    "TF_Nm",
    "oneF",
    "T_prev_Nm",
    "nis",
    "primed",
    "fault_count",
)


def run(cmd, timeout=BUILD_TIMEOUT_S, **kwargs):
    done = subprocess.run([str(c) for c in cmd], capture_output=True, text=True, timeout=timeout, **kwargs)
    assert done.returncode == 0, f"{' '.join(map(str, cmd))} failed:\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
    return done.stdout


def f32(x):
    return float(np.float32(x))


# --------------------------------------------------------------------------------------------
# golden vectors, generated here (fixed seed)
# --------------------------------------------------------------------------------------------


def speed_cases(rng):
    """One p2d_speed_config_t (as a dict of float32-exact values) per method x feedforward x
    anti-windup for a surface PMSM, plus every method x anti-windup for a salient one."""
    cases = []
    combos = [(me, ff, aw, False) for me in range(METHOD) for ff in range(FEEDFORWARD) for aw in range(ANTI_WINDUP)]
    combos += [(me, 3, aw, True) for me in range(METHOD) for aw in range(ANTI_WINDUP)]
    for method, ff, aw, salient in combos:
        J, alpha, zeta = rng.uniform(0.01, 1.0), rng.uniform(1.0, 100.0), rng.uniform(0.5, 1.0)
        Lq = rng.uniform(1e-3, 2e-2)
        cases.append(
            dict(
                J_kgm2=f32(J),
                alpha_radps=f32(alpha),
                zeta=f32(zeta),
                m=1.0 if ff in (0, 1) else f32(rng.uniform(0.5, 3.0)),
                tau_i_s=f32(rng.uniform(1e-3, 5e-2)),
                # Ka around the paper's default 1/Kp (sections 3.2, 3.3), within a factor of about 3
                Ka=f32(rng.uniform(0.3, 3.0) / (J * alpha)),
                Ts_s=f32(1e-3),
                i_max_A=f32(rng.uniform(2.0, 20.0)),
                psi_f_Wb=f32(rng.uniform(0.05, 0.5)),
                Ld_H=f32(Lq * rng.uniform(0.3, 0.8) if salient else Lq),
                Lq_H=f32(Lq),
                pole_pairs=int(rng.integers(1, 8)),
                method=method,
                feedforward=ff,
                anti_windup=aw,
            )
        )
    return cases


def current_cases(rng):
    """One p2d_current_config_t per method x anti-windup x decoupling (salient motor)."""
    cases = []
    for method in range(METHOD):
        for aw in range(ANTI_WINDUP):
            for decouple in (False, True):
                Ts = 1e-4
                cases.append(
                    dict(
                        Rs_ohm=f32(rng.uniform(0.05, 2.0)),
                        Ld_H=f32(rng.uniform(1e-4, 5e-3)),
                        Lq_H=f32(rng.uniform(1e-4, 1e-2)),
                        psi_f_Wb=f32(rng.uniform(0.0, 0.3)),
                        tau_i_s=f32(Ts * rng.uniform(2.0, 50.0)),
                        Ts_s=f32(Ts),
                        method=method,
                        anti_windup=aw,
                        decouple=decouple,
                    )
                )
    return cases


def steps(rng, lo, hi, n=SAMPLES, segments=6):
    """Piecewise-constant sequence with random levels in [lo, hi]."""
    edges = np.sort(rng.choice(np.arange(1, n), segments - 1, replace=False))
    return np.repeat(rng.uniform(lo, hi, segments), np.diff(np.concatenate(([0], edges, [n]))))


def lagged(rng, target, pole, noise):
    """A measurement following target with a first-order lag and noise."""
    y = np.empty_like(target)
    y[0] = 0.0
    for k in range(1, len(target)):
        y[k] = y[k - 1] + pole * (target[k - 1] - y[k - 1])
    return y + noise * rng.standard_normal(len(target))


def speed_inputs(rng, cfg):
    """(SAMPLES, 3) float32: w_ref, w_m, torque limit of the applied command."""
    T_max = 1.5 * cfg["pole_pairs"] * cfg["psi_f_Wb"] * cfg["i_max_A"]
    w_big = 3.0 * T_max / (cfg["J_kgm2"] * cfg["alpha_radps"])  # error that saturates
    w_ref = steps(rng, -w_big, w_big)
    w_m = lagged(rng, w_ref, 0.2, 0.01 * w_big)
    lim = np.full(SAMPLES, np.inf)
    lim[80:95] = 0.3 * T_max  # an external limit below the controller's own
    x = np.stack([w_ref, w_m, lim], axis=1).astype(np.float32)
    x[30, 1] = np.nan  # speed measurement lost
    x[50, 0] = np.inf  # reference overflow
    x[51, 0] = -np.inf
    x[70, 2] = np.nan  # non-finite applied torque
    return x


def current_inputs(rng, cfg):
    """(SAMPLES, 7) float32: id_ref, iq_ref, id, iq, w_e, u_dc, voltage limit of the applied command."""
    id_ref = steps(rng, -10.0, 0.0)
    iq_ref = steps(rng, -20.0, 20.0)
    id_ = lagged(rng, id_ref, 0.3, 0.05)
    iq = lagged(rng, iq_ref, 0.3, 0.05)
    w_e = np.cumsum(rng.normal(0.0, 20.0, SAMPLES))
    u_dc = steps(rng, 5.0, 300.0)  # low DC link saturates the voltage vector
    lim = np.full(SAMPLES, np.inf)
    lim[80:95] = 5.0
    x = np.stack([id_ref, iq_ref, id_, iq, w_e, u_dc, lim], axis=1).astype(np.float32)
    x[30, 2] = np.nan  # current measurement lost
    x[50, 5] = np.nan  # DC-link measurement lost
    x[51, 5] = np.inf
    x[60, 4] = np.inf  # speed overflow
    x[70, 6] = np.nan  # non-finite applied voltage
    return x


def inertia_cases(rng):
    """p2d_inertia_config_t of a small servo, with sampled and period-mean speeds and memories from 5 Ts up."""
    cases = []
    for period_mean in (False, True):
        for J_memory_s, load_memory_s in ((10.0, 0.5), (0.005, 0.005), (1e3, 0.05)):
            J0 = rng.uniform(0.005, 0.05)
            cases.append(
                dict(
                    Ts_s=f32(1e-3),
                    J0_kgm2=f32(J0),
                    J_min_kgm2=f32(J0 / 10),
                    J_max_kgm2=f32(J0 * 10),
                    B_max_Nms=f32(rng.uniform(0.005, 0.05)),
                    T_load_max_Nm=f32(rng.uniform(1.0, 5.0)),
                    sigma_T_Nm=f32(rng.uniform(0.005, 0.1)),
                    J_memory_s=f32(J_memory_s),
                    load_memory_s=f32(load_memory_s),
                    w_f_radps=f32(rng.uniform(10.0, 200.0)),
                    J_rel_sd_max=f32(0.05),
                    speed_is_period_mean=period_mean,
                )
            )
    return cases


def encoder_cases():
    """p2d_encoder_config_t of each estimator, counter width and low-pass (10000-count encoder at 1 kHz and others)."""

    def case(counts_per_rev, counter_bits, estimator, bandwidth_radps, lowpass_radps):
        return dict(
            counts_per_rev=counts_per_rev,
            counter_bits=counter_bits,
            Ts_s=f32(1e-3),
            estimator=estimator,
            bandwidth_radps=f32(bandwidth_radps),
            lowpass_radps=f32(lowpass_radps),
        )

    return [
        case(10000, 16, 0, 200.0, 0.0),
        case(8192, 12, 0, 200.0, 300.0),
        case(10000, 16, 1, 200.0, 0.0),
        case(4096, 32, 1, 1000.0, 500.0),
        case(4, 2, 1, 2000.0, 0.0),
        case(100000, 32, 1, 3.0, 1.5),
    ]


def encoder_inputs(rng, cfg):
    """(SAMPLES,) uint32 counter readings of a trajectory whose speed steps within the measurable range."""
    w_max = 0.4 * np.pi * 2 ** cfg["counter_bits"] / (cfg["counts_per_rev"] * 1e-3)
    w = steps(rng, -min(w_max, 600.0), min(w_max, 600.0))
    theta = rng.uniform(0, 2 * np.pi) + np.cumsum(w) * 1e-3
    counts = np.floor(theta * cfg["counts_per_rev"] / (2 * np.pi)).astype(np.int64)
    offset = int(rng.integers(0, 2 ** cfg["counter_bits"]))
    return ((counts + offset) % 2 ** cfg["counter_bits"]).astype(np.uint32)


def fw_cases(rng):
    """One p2d_field_weakening_config_t per method x anti-windup (a 48 V servo at 10 kHz)."""
    cases = []
    for method in range(METHOD):
        for aw in range(ANTI_WINDUP):
            Ki = rng.uniform(20.0, 200.0)
            cases.append(
                dict(
                    Kp_A_per_V=f32(rng.uniform(0.0, 0.05)),
                    Ki_A_per_Vs=f32(Ki),
                    Ka_V_per_A=f32(rng.uniform(0.1, 1.5e4 / Ki)),
                    Ts_s=f32(1e-4),
                    voltage_ratio=f32(rng.uniform(0.8, 1.0)),
                    id_min_A=f32(-rng.uniform(2.0, 20.0)),
                    method=method,
                    anti_windup=aw,
                )
            )
    return cases


def inertia_inputs(rng, cfg):
    """(SAMPLES, 2) float32: speed and torque of a rigid drive J = 2 J0 under torque steps, quantized speed."""
    J, Ts = 2.0 * cfg["J0_kgm2"], cfg["Ts_s"]
    T = steps(rng, -cfg["T_load_max_Nm"], cfg["T_load_max_Nm"], segments=8)
    w = np.concatenate(([0.0], np.cumsum(Ts / J * (T[1:] - 0.3 * cfg["T_load_max_Nm"]))))
    w = np.round(w / 0.4) * 0.4 + 0.01 * rng.standard_normal(SAMPLES)  # a coarse speed resolution
    x = np.stack([w, T + 0.02 * rng.standard_normal(SAMPLES)], axis=1).astype(np.float32)
    x[30, 0] = np.nan  # speed measurement lost
    x[50, 1] = np.inf  # torque overflow
    x[70, 0] = 3e38  # an update that overflows
    return x


def fw_inputs(rng):
    """(SAMPLES, 3) float32: ud, uq (magnitude steps around the range of the DC link), u_dc."""
    norm = steps(rng, 5.0, 45.0)
    angle = rng.uniform(0.5, 2.5, SAMPLES)
    x = np.stack([norm * np.cos(angle), norm * np.sin(angle), steps(rng, 30.0, 60.0)], axis=1).astype(np.float32)
    x[30, 0] = np.nan  # voltage command lost
    x[50, 2] = np.nan  # DC-link measurement lost
    x[51, 1] = np.inf
    x[60, 0] = 1e20  # ||u_dq||^2 overflows
    x[70, 2] = -5.0  # negative DC link: 0 V range
    return x


def speed_fw_inputs(rng, cfg):
    """(SAMPLES, 4) float32: w_ref, w_m, id_fw (from beyond -i_max to above 0), torque limit of the applied command."""
    x = speed_inputs(rng, cfg)
    id_fw = steps(rng, -1.2 * cfg["i_max_A"], 0.2 * cfg["i_max_A"]).astype(np.float32)
    id_fw[40] = np.nan  # field-weakening current lost
    id_fw[41] = -np.inf
    return np.insert(x, 2, id_fw, axis=1)


def c_value(value):
    """Exact C99 initializer of a float32, int or bool value."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return f"{value}"
    return f"{float(value).hex()}f"  # hexadecimal float: exact


def vectors_header(v):
    """Text of p2d_target_vectors.h (see csrc/target/target_vectors.c) for the vectors v."""
    speed, speed_in, current, current_in = v["speed"], v["speed_in"], v["current"], v["current_in"]
    inertia, inertia_in = v["inertia"], v["inertia_in"]
    speed_enums = dict(method="p2d_method_t", feedforward="p2d_feedforward_t", anti_windup="p2d_anti_windup_t")

    def config(cfg, enums):
        return (
            "{"
            + ", ".join(f".{k} = ({enums[k]}){v}" if k in enums else f".{k} = {c_value(v)}" for k, v in cfg.items())
            + "}"
        )

    def words(x):
        return "{" + ",\n".join("{" + ", ".join(f"0x{w:08x}u" for w in row) + "}" for row in x.view(np.uint32)) + "}"

    text = [
        "/* written by tests/test_target_qemu.py */",
        f"#define P2D_VEC_SAMPLES {SAMPLES}u",
        f"#define P2D_VEC_SPEED_CASES {len(speed)}u",
        f"#define P2D_VEC_CURRENT_CASES {len(current)}u",
        f"#define P2D_VEC_INERTIA_CASES {len(inertia)}u",
        "static const p2d_speed_config_t p2d_vec_speed_config[P2D_VEC_SPEED_CASES] = {",
        ",\n".join(config(c, speed_enums) for c in speed),
        "};",
        "static const uint32_t p2d_vec_speed_input[P2D_VEC_SPEED_CASES][P2D_VEC_SAMPLES][3] = {",
        ",\n".join(words(x) for x in speed_in),
        "};",
        "static const p2d_current_config_t p2d_vec_current_config[P2D_VEC_CURRENT_CASES] = {",
        ",\n".join(config(c, dict(method="p2d_method_t", anti_windup="p2d_anti_windup_t")) for c in current),
        "};",
        "static const uint32_t p2d_vec_current_input[P2D_VEC_CURRENT_CASES][P2D_VEC_SAMPLES][7] = {",
        ",\n".join(words(x) for x in current_in),
        "};",
        "static const uint32_t p2d_vec_speed_fw_input[P2D_VEC_SPEED_CASES][P2D_VEC_SAMPLES][4] = {",
        ",\n".join(words(x) for x in v["speed_fw_in"]),
        "};",
        f"#define P2D_VEC_ENCODER_CASES {len(v['encoder'])}u",
        "static const p2d_encoder_config_t p2d_vec_encoder_config[P2D_VEC_ENCODER_CASES] = {",
        ",\n".join(config(c, dict(estimator="p2d_estimator_t")) for c in v["encoder"]),
        "};",
        "static const uint32_t p2d_vec_encoder_input[P2D_VEC_ENCODER_CASES][P2D_VEC_SAMPLES] = {",
        ",\n".join("{" + ", ".join(f"0x{w:08x}u" for w in x.tolist()) + "}" for x in v["encoder_in"]),
        "};",
        f"#define P2D_VEC_FW_CASES {len(v['fw'])}u",
        "static const p2d_field_weakening_config_t p2d_vec_fw_config[P2D_VEC_FW_CASES] = {",
        ",\n".join(config(c, dict(method="p2d_method_t", anti_windup="p2d_anti_windup_t")) for c in v["fw"]),
        "};",
        "static const uint32_t p2d_vec_fw_input[P2D_VEC_FW_CASES][P2D_VEC_SAMPLES][3] = {",
        ",\n".join(words(x) for x in v["fw_in"]),
        "};",
        "static const p2d_inertia_config_t p2d_vec_inertia_config[P2D_VEC_INERTIA_CASES] = {",
        ",\n".join(config(c, {}) for c in inertia),
        "};",
        "static const uint32_t p2d_vec_inertia_input[P2D_VEC_INERTIA_CASES][P2D_VEC_SAMPLES][2] = {",
        ",\n".join(words(x) for x in inertia_in),
        "};",
        "",
    ]
    return "\n".join(text)


@pytest.fixture(scope="module")
def vectors():
    rng = np.random.default_rng(20240615)
    speed = speed_cases(rng)
    current = current_cases(rng)
    v = dict(
        speed=speed,
        speed_in=[speed_inputs(rng, c) for c in speed],
        current=current,
        current_in=[current_inputs(rng, c) for c in current],
    )
    # drawn after the vectors above, which stay as they were
    v["speed_fw_in"] = [speed_fw_inputs(rng, c) for c in speed]
    v["encoder"] = encoder_cases()
    v["encoder_in"] = [encoder_inputs(rng, c) for c in v["encoder"]]
    v["fw"] = fw_cases(rng)
    v["fw_in"] = [fw_inputs(rng) for _ in v["fw"]]
    inertia_rng = np.random.default_rng(20261124)  # its own stream: the controllers' vectors stay as they were
    v["inertia"] = inertia_cases(inertia_rng)
    v["inertia_in"] = [inertia_inputs(inertia_rng, c) for c in v["inertia"]]
    return v


# --------------------------------------------------------------------------------------------
# host side: the same C through pmsm2dof._core
# --------------------------------------------------------------------------------------------


def word(cdata, field):
    """The 32-bit word of a float, bool (0/1) or uint32 field, as the target prints it."""
    value = getattr(cdata, field)
    if isinstance(value, bool):
        return int(value)
    if isinstance(value, int):
        return value & 0xFFFFFFFF  # int32 as its two's complement word
    return int(ffi.cast("uint32_t *", ffi.addressof(cdata, field))[0])


def limit(x, lim):
    """The applied command of target_vectors.c: x limited to [-lim, lim]; NaN when lim is NaN."""
    x, lim = np.float32(x), np.float32(lim)
    if not x <= lim:
        x = lim
    if not x >= -lim:
        x = -lim
    return float(x)


def host_speed(cfg, inputs):
    ctl = ffi.new("p2d_speed_t *")
    status = lib.p2d_speed_init(ctl, ffi.new("p2d_speed_config_t *", cfg))
    rows = []
    if status == 0:
        for w_ref, w_m, lim in inputs.tolist():
            out = ffi.new("p2d_speed_output_t *")
            lib.p2d_speed_compute(ctl, w_ref, w_m, out)
            lib.p2d_speed_update(ctl, out, limit(out.T_ref_Nm, lim))
            rows.append([word(out[0], f) for f in SPEED_FIELDS[:10]] + [word(ctl[0], f) for f in SPEED_FIELDS[10:]])
    return status, rows


def host_speed_fw(cfg, inputs):
    ctl = ffi.new("p2d_speed_t *")
    status = lib.p2d_speed_init(ctl, ffi.new("p2d_speed_config_t *", cfg))
    rows = []
    if status == 0:
        for w_ref, w_m, id_fw, lim in inputs.tolist():
            out = ffi.new("p2d_speed_output_t *")
            lib.p2d_speed_compute_fw(ctl, w_ref, w_m, id_fw, out)
            lib.p2d_speed_update(ctl, out, limit(out.T_ref_Nm, lim))
            rows.append([word(out[0], f) for f in SPEED_FIELDS[:10]] + [word(ctl[0], f) for f in SPEED_FIELDS[10:]])
    return status, rows


def host_encoder(cfg, readings):
    enc = ffi.new("p2d_encoder_t *")
    status = lib.p2d_encoder_init(enc, ffi.new("p2d_encoder_config_t *", cfg))
    rows = []
    if status == 0:
        lib.p2d_encoder_reset(enc, int(readings[0]), 0.0)
        for count in readings.tolist():
            out = ffi.new("p2d_encoder_output_t *")
            lib.p2d_encoder_step(enc, count, out)
            rows.append([word(out[0], f) for f in ENCODER_FIELDS[:4]] + [word(enc[0], f) for f in ENCODER_FIELDS[4:]])
    return status, rows


def host_fw(cfg, inputs):
    fw = ffi.new("p2d_field_weakening_t *")
    status = lib.p2d_field_weakening_init(fw, ffi.new("p2d_field_weakening_config_t *", cfg))
    rows = []
    if status == 0:
        for ud, uq, u_dc in inputs.tolist():
            out = ffi.new("p2d_field_weakening_output_t *")
            lib.p2d_field_weakening_step(fw, ud, uq, u_dc, out)
            rows.append([word(out[0], f) for f in FW_FIELDS[:7]] + [word(fw[0], f) for f in FW_FIELDS[7:]])
    return status, rows


def host_current(cfg, inputs):
    ctl = ffi.new("p2d_current_t *")
    status = lib.p2d_current_init(ctl, ffi.new("p2d_current_config_t *", cfg))
    rows = []
    if status == 0:
        for id_ref, iq_ref, id_, iq, w_e, u_dc, lim in inputs.tolist():
            out = ffi.new("p2d_current_output_t *")
            lib.p2d_current_compute(ctl, id_ref, iq_ref, id_, iq, w_e, u_dc, out)
            lib.p2d_current_update(ctl, out, limit(out.ud_ref_V, lim), limit(out.uq_ref_V, lim))
            rows.append([word(out[0], f) for f in CURRENT_FIELDS[:8]] + [word(ctl[0], f) for f in CURRENT_FIELDS[8:]])
    return status, rows


def host_inertia(cfg, inputs):
    est = ffi.new("p2d_inertia_t *")
    status = lib.p2d_inertia_init(est, ffi.new("p2d_inertia_config_t *", cfg))
    rows = []
    if status == 0:
        for w_m, T_e in inputs.tolist():
            out = ffi.new("p2d_inertia_output_t *")
            lib.p2d_inertia_step(est, w_m, T_e, out)
            rows.append(
                ([word(out[0], f) for f in INERTIA_OUTPUT_FIELDS], [word(est[0], f) for f in INERTIA_STATE_FIELDS])
            )
    return status, rows


# --------------------------------------------------------------------------------------------
# builds
# --------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def cross_build(tmp_path_factory, vectors):
    """The csrc cross build: the library, the probe programs and the golden-vector runner."""
    tmp = tmp_path_factory.mktemp("cortex-m4f")
    (tmp / "p2d_target_vectors.h").write_text(vectors_header(vectors))
    build = tmp / "build"
    run(["cmake", "-S", CSRC, "-B", build, f"-DCMAKE_TOOLCHAIN_FILE={TOOLCHAIN}", f"-DP2D_TARGET_VECTORS_DIR={tmp}"])
    run(["cmake", "--build", build, "-j2"])
    return build


@pytest.fixture(scope="module")
def firmware_build(tmp_path_factory):
    """The firmware example, configured from a fresh build directory."""
    build = tmp_path_factory.mktemp("firmware") / "build"
    run(
        [
            "cmake",
            "-S",
            FIRMWARE,
            "-B",
            build,
            f"-DCMAKE_TOOLCHAIN_FILE={TOOLCHAIN}",
            f"-DPython3_EXECUTABLE={sys.executable}",
        ]
    )
    run(["cmake", "--build", build, "-j2"])
    return build


def elf_symbols(elf):
    out = run(["arm-none-eabi-nm", "--defined-only", elf])
    return {p[2]: int(p[0], 16) for p in (line.split() for line in out.splitlines()) if len(p) == 3}


@needs_cross
def test_library_cross_builds_for_cortex_m4f_hard_float(cross_build):
    lib_a = cross_build / "libpmsm2dof_controller.a"
    members = run(["arm-none-eabi-ar", "t", lib_a]).split()
    assert sorted(members) == sorted(f"{p.name}.obj" for p in (CSRC / "src").glob("*.c"))
    attributes = run(["arm-none-eabi-readelf", "-A", lib_a])
    # one block per object, each Armv7E-M Thumb-2 with the single-precision FPU, floats in FPU registers
    for tag in (
        "Tag_CPU_arch: v7E-M",
        "Tag_THUMB_ISA_use: Thumb-2",
        "Tag_FP_arch: VFPv4-D16",
        "Tag_ABI_HardFP_use: SP only",
        "Tag_ABI_VFP_args: VFP registers",
    ):
        assert attributes.count(tag) == len(members), tag


@needs_cross
def test_firmware_example_builds_with_the_generated_header(firmware_build):
    header = (firmware_build / "generated" / "p2d_config.h").read_text()
    assert '"paper experiment 1"' in header and "#define P2D_CONFIG_CURRENT_PER_SPEED 10u" in header
    assert "static const p2d_speed_config_t p2d_config_speed" in header
    assert "static const p2d_current_config_t p2d_config_current" in header
    assert (firmware_build / "virtual_drive.elf").read_bytes().startswith(b"\x7fELF")
    elf = firmware_build / "firmware.elf"
    symbols = elf_symbols(elf)
    for name in (
        "Reset_Handler",
        "SysTick_Handler",
        "foc_isr",
        "p2d_speed_compute",
        "p2d_speed_update",
        "p2d_current_compute",
        "p2d_current_update",
    ):
        assert name in symbols, name
    # the vector table at address 0: initial SP at the top of SRAM, reset and SysTick (exception 15) handlers
    words = vector_table(elf)
    assert words[0] == 0x20000000 + 4 * 1024 * 1024
    assert words[1] == symbols["Reset_Handler"] | 1
    assert words[15] == symbols["SysTick_Handler"] | 1


def vector_table(elf):
    """The 16 words of the Cortex-M vector table of the ELF."""
    dump = run(["arm-none-eabi-objdump", "-s", "-j", ".isr_vector", elf])
    data = bytearray()
    for line in dump.splitlines():
        m = re.match(r"^ ([0-9a-f]{4,8}) ((?:[0-9a-f]{8} ?){1,4})", line)
        if m:
            data += bytes.fromhex(m.group(2).replace(" ", ""))
    return np.frombuffer(bytes(data[:64]), dtype="<u4").tolist()


@needs_cross
@needs_qemu
def test_the_firmware_idles_with_its_interrupt_running_and_the_controllers_off(firmware_build, tmp_path):
    """On QEMU, SysTick drives the control interrupt (link_isr) from power-up; with no master to start
    a run the power stage stays off and the controllers never run (the runs, with the current loop
    every interrupt and the speed loop at the configured ratio, are tests/test_firmware.py's)."""
    elf = firmware_build / "firmware.elf"
    symbols = elf_symbols(elf)
    watched = ("link_isr", "foc_isr", "p2d_current_compute", "p2d_speed_compute", "p2d_default_handler")
    log = tmp_path / "exec.log"
    # log only the translation blocks that start at the entry of a watched function
    dfilter = ",".join(f"{symbols[name]:#x}+2" for name in watched)
    qemu = subprocess.Popen(
        [*QEMU, "-d", "exec,nochain", "-dfilter", dfilter, "-D", str(log), "-kernel", str(elf)],
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )
    time.sleep(2.0)
    qemu.send_signal(signal.SIGTERM)
    qemu.communicate(timeout=30)
    entries = {name: 0 for name in watched}
    address = {symbols[name]: name for name in watched}
    for line in log.read_text().splitlines():
        m = re.match(r"^Trace \d+: \S+ \[[0-9a-f]+/([0-9a-f]+)/", line)
        if m and int(m.group(1), 16) in address:
            entries[address[int(m.group(1), 16)]] += 1
    assert entries["link_isr"] >= 100, entries
    assert entries["p2d_default_handler"] == 0, "a fault handler ran"
    assert entries["foc_isr"] == entries["p2d_current_compute"] == 0, entries
    # the speed controller's only call is foc_init's validation (foc_start is a run's)
    assert entries["p2d_speed_compute"] <= 1, entries


def is_nan(w):
    return (w & 0x7F800000) == 0x7F800000 and (w & 0x007FFFFF) != 0


def parse_target_output(text):
    """({tag: {case: status}}, {tag: {(case, k): [words]}}) of target_vectors.c's output."""
    status, rows = {t: {} for t in "SCFEWJ"}, {t: {} for t in "SCFEWJK"}
    for line in text.splitlines():
        p = line.split()
        if len(p) == 4 and p[0] == "I":
            status[p[1]][int(p[2], 16)] = int(p[3], 16)
        elif p and p[0] in rows:
            rows[p[0]][(int(p[1], 16), int(p[2], 16))] = [int(w, 16) for w in p[3:]]
    return status, rows


@needs_cross
@needs_qemu
def test_golden_vectors_on_qemu_equal_host_to_the_bit(cross_build, vectors):
    elf = cross_build / "target" / "p2d_target_vectors"
    done = subprocess.run(
        [*QEMU, "-kernel", str(elf)], capture_output=True, text=True, timeout=QEMU_TIMEOUT_S, stdin=subprocess.DEVNULL
    )
    # semihosting output arrives on stderr
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stderr.splitlines()[-1] == "END"
    target_status, target_rows = parse_target_output(done.stderr)

    mismatches = []
    seen = {}
    for tag, cases, inputs, host, fields, exact in (
        ("S", vectors["speed"], vectors["speed_in"], host_speed, SPEED_FIELDS, SPEED_EXACT),
        ("C", vectors["current"], vectors["current_in"], host_current, CURRENT_FIELDS, CURRENT_EXACT),
        ("F", vectors["speed"], vectors["speed_fw_in"], host_speed_fw, SPEED_FIELDS, SPEED_EXACT),
        ("E", vectors["encoder"], vectors["encoder_in"], host_encoder, ENCODER_FIELDS, ENCODER_EXACT),
        ("W", vectors["fw"], vectors["fw_in"], host_fw, FW_FIELDS, FW_EXACT),
    ):
        for c, (cfg, x) in enumerate(zip(cases, inputs)):
            status, host_rows = host(cfg, x)
            assert status == 0 and target_status[tag][c] == 0, (tag, c, status, target_status[tag].get(c), cfg)
            for k, host_row in enumerate(host_rows):
                row = target_rows[tag][(c, k)]
                assert len(row) == len(fields), (tag, c, k, row)
                path = (tag, path_of(tag, dict(zip(fields, row))))
                seen[path] = seen.get(path, 0) + 1
                for name, h, t in zip(fields, host_row, row):
                    if h == t:
                        continue
                    if name not in exact and is_nan(h) and is_nan(t):
                        continue  # NaN payloads may differ (Arm and x86 default NaNs)
                    mismatches.append(f"{tag} case {c} sample {k} {name}: target {t:08x}, host {h:08x} ({cfg})")
    for tag, cases in (("S", "speed"), ("C", "current"), ("F", "speed"), ("E", "encoder"), ("W", "fw")):
        assert len(target_rows[tag]) == len(vectors[cases]) * SAMPLES, tag
    assert not mismatches, (
        f"{len(mismatches)} words differ (is pmsm2dof._core older than csrc/src? "
        "rebuild it with pip install -e .):\n" + "\n".join(mismatches[:20])
    )
    # the vectors went through every path: unsaturated, saturated, non-finite (speed, current, field-weakening
    # entry); both directions of the counter; field weakening off, weakening, at id_min and faulted
    assert set(seen) == set(PATHS), seen
    assert min(seen.values()) >= 20, seen


PATHS = [(t, p) for t in "SCF" for p in ("unsaturated", "saturated", "fault")] + [
    ("E", "forward"),
    ("E", "backward"),
    ("W", "off"),
    ("W", "weakening"),
    ("W", "at_id_min"),
    ("W", "fault"),
]


def path_of(tag, row):
    """The path of the controller that gave the row of words (PATHS)."""
    if tag == "E":
        return "backward" if row["dn_counts"] & 0x80000000 else "forward"
    if tag == "W":
        return "fault" if row["fault"] else "at_id_min" if row["at_id_min"] else "weakening" if row["active"] else "off"
    return "fault" if row["fault"] else "saturated" if row["saturated"] else "unsaturated"


@needs_cross
@needs_qemu
def test_inertia_golden_vectors_on_qemu_equal_host_to_the_bit(cross_build, vectors):
    """The estimator's outputs and its whole state, every sample, on QEMU and on the host: equal words.

    Its state is finite by the non-finite policy, so every word must match to the bit; so must the outputs.
    """
    elf = cross_build / "target" / "p2d_target_vectors"
    done = subprocess.run(
        [*QEMU, "-kernel", str(elf)], capture_output=True, text=True, timeout=QEMU_TIMEOUT_S, stdin=subprocess.DEVNULL
    )
    assert done.returncode == 0, done.stderr[-3000:]
    target_status, target_rows = parse_target_output(done.stderr)
    mismatches, seen = [], {"updated": 0, "fault": 0, "valid": 0}
    for c, (cfg, x) in enumerate(zip(vectors["inertia"], vectors["inertia_in"])):
        status, host_rows = host_inertia(cfg, x)
        assert status == 0 and target_status["J"][c] == 0, (c, status, target_status["J"].get(c), cfg)
        for k, (host_out, host_state) in enumerate(host_rows):
            for tag, fields, host in (("J", INERTIA_OUTPUT_FIELDS, host_out), ("K", INERTIA_STATE_FIELDS, host_state)):
                row = target_rows[tag][(c, k)]
                assert len(row) == len(fields), (tag, c, k, row)
                mismatches += [
                    f"{tag} case {c} sample {k} {name}: target {t:08x}, host {h:08x} ({cfg})"
                    for name, h, t in zip(fields, host, row)
                    if h != t
                ]
            named = dict(zip(INERTIA_OUTPUT_FIELDS, host_out))
            seen["updated"] += named["updated"]
            seen["fault"] += named["fault"]
            seen["valid"] += named["J_valid"]
    assert len(target_rows["J"]) == len(target_rows["K"]) == len(vectors["inertia"]) * SAMPLES
    assert not mismatches, (
        f"{len(mismatches)} words differ (is pmsm2dof._core older than csrc/src? "
        "rebuild it with pip install -e .):\n" + "\n".join(mismatches[:20])
    )
    # the vectors went through updates, faults and valid estimates
    assert seen["fault"] >= 3 * len(vectors["inertia"]) and seen["updated"] > 50 * len(vectors["inertia"]), seen
    print(f"\ninertia golden vectors: {len(vectors['inertia'])} cases x {SAMPLES} samples, {seen}")
    assert seen["valid"] > 0, seen
