"""The filters on the MCU's instruction set: golden vectors on QEMU equal the host to the bit.

The notch and low-pass filters (csrc/include/pmsm2dof/filter.h) compute their
coefficients from tan(pi f0 Ts), written with +, *, / and fmaf only because the
libm tanf, sinf and cosf of the host and of newlib may differ in the last bit.
This test checks that the coefficients, the outputs and the states of the
filters, and of the speed controller with torque filters, are the same float32
words on a Cortex-M4F (QEMU ``-M mps2-an386``, csrc/target/target_filter_vectors.c)
and on the host (``pmsm2dof._core``), for random configurations from near DC to
near the Nyquist frequency and inputs with steps, sinusoids, NaN, inf and 3e38.
Only NaN payloads may differ (Arm and x86 default NaNs), and only in T_unsat.
"""

import subprocess

import numpy as np
import pytest
from test_target_qemu import CSRC, QEMU, TOOLCHAIN, needs_cross, needs_qemu

from pmsm2dof._core import ffi, lib

#: Slow (builds, emulators, fuzzing, browsers or whole reproductions): run by the full suite.
pytestmark = [pytest.mark.slow, needs_cross, needs_qemu]

SAMPLES = 120
FILTER_FIELDS = ("notch_freq_Hz", "notch_width_Hz", "notch_depth", "lowpass_freq_Hz", "lowpass_zeta")


def f32(x):
    return float(np.float32(x))


def filter_case(rng, Ts):
    """A random chain at Ts: a notch, a low-pass or both, from near DC to near the Nyquist frequency."""
    nyquist = 0.5 / Ts
    sections = rng.integers(1, 4)
    cfg = dict.fromkeys(FILTER_FIELDS, 0.0)
    if sections & 1:
        f0 = nyquist * 10 ** rng.uniform(-4, np.log10(0.98))
        cfg.update(
            notch_freq_Hz=f32(f0),
            notch_width_Hz=f32(min(f0 * 10 ** rng.uniform(-2, 0.5), 0.9 * nyquist)),
            notch_depth=f32(rng.uniform(0, 0.7)),
        )
    if sections & 2:
        cfg.update(
            lowpass_freq_Hz=f32(nyquist * 10 ** rng.uniform(-4, np.log10(0.98))),
            lowpass_zeta=f32(10 ** rng.uniform(-2, 1)),
        )
    return cfg


def filter_inputs(rng):
    k = np.arange(SAMPLES)
    x = np.repeat(rng.uniform(-5, 5, 6), SAMPLES // 6) + rng.uniform(0, 2) * np.sin(rng.uniform(0, np.pi) * k)
    x = x.astype(np.float32)
    x[40], x[41], x[90] = np.nan, np.inf, 3e38  # non-finite and overflowing samples
    return x


def speed_case(rng, method, aw, salient):
    J, alpha = rng.uniform(0.01, 1.0), rng.uniform(5.0, 100.0)
    Lq = rng.uniform(1e-3, 2e-2)
    cfg = dict(
        J_kgm2=f32(J),
        alpha_radps=f32(alpha),
        zeta=f32(rng.uniform(0.5, 1.0)),
        m=1.0,
        tau_i_s=0.0,
        Ka=f32(rng.uniform(0.3, 1.0) / (J * alpha)),
        Ts_s=f32(1e-3),
        i_max_A=f32(rng.uniform(2.0, 20.0)),
        psi_f_Wb=f32(rng.uniform(0.05, 0.5)),
        Ld_H=f32(Lq * 0.6 if salient else Lq),
        Lq_H=f32(Lq),
        pole_pairs=int(rng.integers(1, 8)),
        method=method,
        feedforward=1,
        anti_windup=aw,
    )
    # filters of a drive-train resonance, well above the speed loop (a low-pass near the loop's bandwidth
    # makes the anti-windup loop through it unstable, which set_filter refuses)
    sections = rng.integers(1, 4)
    filt = dict.fromkeys(FILTER_FIELDS, 0.0)
    if sections & 1:
        filt.update(
            notch_freq_Hz=f32(rng.uniform(30, 300)),
            notch_width_Hz=f32(rng.uniform(5, 50)),
            notch_depth=f32(rng.uniform(0, 0.5)),
        )
    if sections & 2:
        filt.update(lowpass_freq_Hz=f32(rng.uniform(100, 450)), lowpass_zeta=f32(rng.uniform(0.3, 1.0)))
    return cfg, filt


def speed_inputs(rng, cfg):
    T_max = 1.5 * cfg["pole_pairs"] * cfg["psi_f_Wb"] * cfg["i_max_A"]
    w_big = 3.0 * T_max / (cfg["J_kgm2"] * cfg["alpha_radps"])
    w_ref = np.repeat(rng.uniform(-w_big, w_big, 6), SAMPLES // 6)
    w_m = np.zeros(SAMPLES)  # a measurement lagging the reference: large errors after each step
    for k in range(1, SAMPLES):
        w_m[k] = w_m[k - 1] + 0.2 * (w_ref[k - 1] - w_m[k - 1])
    w_m += 0.01 * w_big * rng.standard_normal(SAMPLES)
    lim = np.full(SAMPLES, np.inf)
    lim[80:95] = 0.3 * T_max
    x = np.stack([w_ref, w_m, lim], axis=1).astype(np.float32)
    x[30, 1], x[50, 0], x[70, 2] = np.nan, np.inf, np.nan
    return x


@pytest.fixture(scope="module")
def vectors():
    rng = np.random.default_rng(16)
    filters = [(filter_case(rng, Ts), Ts) for Ts in rng.choice([1e-4, 5e-4, 1e-3, 1e-2], 40)]
    speed = [speed_case(rng, m, aw, False) for m in range(3) for aw in range(3)]
    speed += [speed_case(rng, 2, aw, True) for aw in range(3)]
    return dict(
        filters=filters,
        filter_in=[filter_inputs(rng) for _ in filters],
        speed=speed,
        speed_in=[speed_inputs(rng, cfg) for cfg, _ in speed],
    )


def words(x):
    return "{" + ", ".join(f"0x{w:08x}u" for w in np.asarray(x, dtype=np.float32).view(np.uint32).ravel()) + "}"


def c_struct(cfg, enums=()):
    return (
        "{"
        + ", ".join(
            f".{k} = ({enums[k]}){v}"
            if k in enums
            else f".{k} = {v}u"
            if isinstance(v, int)
            else f".{k} = {float(v).hex()}f"
            for k, v in cfg.items()
        )
        + "}"
    )


def vectors_header(v):
    enums = dict(method="p2d_method_t", feedforward="p2d_feedforward_t", anti_windup="p2d_anti_windup_t")
    speed_in = ",\n".join("{" + ", ".join(words(row) for row in x) + "}" for x in v["speed_in"])
    return "\n".join(
        [
            "/* written by tests/test_target_qemu_filter.py */",
            f"#define P2D_FVEC_SAMPLES {SAMPLES}u",
            f"#define P2D_FVEC_FILTER_CASES {len(v['filters'])}u",
            f"#define P2D_FVEC_SPEED_CASES {len(v['speed'])}u",
            "static const p2d_filter_config_t p2d_fvec_filter_config[P2D_FVEC_FILTER_CASES] = {",
            ",\n".join(c_struct(cfg) for cfg, _ in v["filters"]),
            "};",
            "static const float p2d_fvec_filter_Ts[P2D_FVEC_FILTER_CASES] = {",
            ", ".join(f"{f32(Ts).hex()}f" for _, Ts in v["filters"]),
            "};",
            "static const uint32_t p2d_fvec_filter_input[P2D_FVEC_FILTER_CASES][P2D_FVEC_SAMPLES] = {",
            ",\n".join(words(x) for x in v["filter_in"]),
            "};",
            "static const p2d_speed_config_t p2d_fvec_speed_config[P2D_FVEC_SPEED_CASES] = {",
            ",\n".join(c_struct(cfg, enums) for cfg, _ in v["speed"]),
            "};",
            "static const p2d_filter_config_t p2d_fvec_speed_filter[P2D_FVEC_SPEED_CASES] = {",
            ",\n".join(c_struct(f) for _, f in v["speed"]),
            "};",
            "static const uint32_t p2d_fvec_speed_input[P2D_FVEC_SPEED_CASES][P2D_FVEC_SAMPLES][3] = {",
            speed_in,
            "};",
            "",
        ]
    )


def word(x):
    if isinstance(x, bool):
        return int(x)
    if isinstance(x, int):
        return x
    return int(np.array(x, dtype=np.float32).view(np.uint32))


def state_words(s):
    return [word(s.notch.s1), word(s.notch.s2), word(s.lowpass.s1), word(s.lowpass.s2)]


def host_filter(cfg, Ts, x):
    """(status, coefficient words, rows) of the host build, as target_filter_vectors.c prints them."""
    f = ffi.new("p2d_filter_t *")
    status = lib.p2d_filter_init(f, ffi.new("p2d_filter_config_t *", cfg), f32(Ts))
    if status != lib.P2D_OK:
        return status, None, []
    c = f.coef[f.active]
    coef = [word(getattr(s, n)) for s in (c.notch, c.lowpass) for n in ("g", "k", "g_h", "c_band")]
    out, rows = ffi.new("p2d_filter_output_t *"), []
    for xi in x.tolist():
        lib.p2d_filter_step(f, xi, out)
        rows.append([word(out.y), int(out.fault), *state_words(f.state), f.fault_count])
    return status, coef, rows


def limit(x, lim):
    x, lim = np.float32(x), np.float32(lim)
    if not x <= lim:
        x = lim
    if not x >= -lim:
        x = -lim
    return float(x)


def host_speed(cfg, filt, x):
    ctl = ffi.new("p2d_speed_t *")
    status = lib.p2d_speed_init(ctl, ffi.new("p2d_speed_config_t *", cfg))
    if status == lib.P2D_OK:
        status = lib.p2d_speed_set_filter(ctl, ffi.new("p2d_filter_config_t *", filt))
    rows = []
    if status == lib.P2D_OK:
        out = ffi.new("p2d_speed_output_t *")
        for w_ref, w_m, lim in x.tolist():
            lib.p2d_speed_compute(ctl, w_ref, w_m, out)
            lib.p2d_speed_update(ctl, out, limit(out.T_ref_Nm, lim))
            rows.append(
                [
                    word(out.T_unsat_Nm),
                    word(out.T_ref_Nm),
                    word(out.iq_ref_A),
                    int(out.saturated),
                    int(out.fault),
                    word(ctl.x_Nm),
                    *state_words(ctl.filter),
                    ctl.fault_count,
                ]
            )
    return status, rows


def is_nan(w):
    return (w & 0x7F800000) == 0x7F800000 and (w & 0x007FFFFF) != 0


@pytest.fixture(scope="module")
def target_output(tmp_path_factory, vectors):
    tmp = tmp_path_factory.mktemp("cortex-m4f-filters")
    (tmp / "p2d_target_filter_vectors.h").write_text(vectors_header(vectors))
    build = tmp / "build"
    for cmd in (
        [
            "cmake",
            "-S",
            CSRC,
            "-B",
            build,
            f"-DCMAKE_TOOLCHAIN_FILE={TOOLCHAIN}",
            f"-DP2D_TARGET_FILTER_VECTORS_DIR={tmp}",
        ],
        ["cmake", "--build", build, "-j2", "--target", "p2d_target_filter_vectors"],
    ):
        done = subprocess.run([str(c) for c in cmd], capture_output=True, text=True, timeout=600)
        assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    done = subprocess.run(
        [*QEMU, "-kernel", str(build / "target" / "p2d_target_filter_vectors")],
        capture_output=True,
        text=True,
        timeout=120,
        stdin=subprocess.DEVNULL,
    )
    assert done.returncode == 0 and done.stderr.splitlines()[-1] == "END", done.stderr[-3000:]
    out = {}
    for line in done.stderr.splitlines():  # semihosting output arrives on stderr
        p = line.split()
        if p and p[0] == "I":
            out[("I", p[1], int(p[2], 16))] = int(p[3], 16)
        elif p and p[0] == "K":
            out[("K", int(p[2], 16))] = [int(w, 16) for w in p[3:]]
        elif p and p[0] in ("F", "S"):
            out[(p[0], int(p[1], 16), int(p[2], 16))] = [int(w, 16) for w in p[3:]]
    return out


def test_filter_coefficients_and_outputs_on_qemu_equal_host_to_the_bit(vectors, target_output):
    accepted, faults, mismatches = 0, 0, []
    for c, ((cfg, Ts), x) in enumerate(zip(vectors["filters"], vectors["filter_in"])):
        status, coef, rows = host_filter(cfg, Ts, x)
        assert target_output[("I", "F", c)] == status, (c, cfg, Ts)
        if status != lib.P2D_OK:
            continue
        accepted += 1
        if target_output[("K", c)] != coef:
            mismatches.append(f"filter case {c} coefficients: target {target_output[('K', c)]}, host {coef}")
        for k, row in enumerate(rows):
            faults += row[1]
            if target_output[("F", c, k)] != row:
                mismatches.append(f"filter case {c} sample {k}: target {target_output[('F', c, k)]}, host {row}")
    assert not mismatches, "\n".join(mismatches[:20])
    assert accepted >= 35 and faults >= 2 * accepted  # the NaN and inf samples at least


def test_filtered_speed_controller_on_qemu_equals_host_to_the_bit(vectors, target_output):
    seen = {"unsaturated": 0, "saturated": 0, "fault": 0}
    mismatches = []
    for c, ((cfg, filt), x) in enumerate(zip(vectors["speed"], vectors["speed_in"])):
        status, rows = host_speed(cfg, filt, x)
        assert status == lib.P2D_OK and target_output[("I", "S", c)] == status, (c, status, cfg, filt)
        for k, row in enumerate(rows):
            target = target_output[("S", c, k)]
            seen["fault" if row[4] else "saturated" if row[3] else "unsaturated"] += 1
            same = [h == t or (i == 0 and is_nan(h) and is_nan(t)) for i, (h, t) in enumerate(zip(row, target))]
            if len(target) != len(row) or not all(same):
                mismatches.append(f"speed case {c} sample {k}: target {target}, host {row}")
    assert not mismatches, "\n".join(mismatches[:20])
    assert min(seen.values()) >= 10, seen
