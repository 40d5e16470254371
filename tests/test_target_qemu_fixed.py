"""The fixed-point speed controllers on a Cortex-M3 and a Cortex-M0: bit-equal to the host, integer-only steps.

The library cross-builds for the Cortex-M3 (``csrc/cmake/arm-none-eabi-cortex-m3.cmake``, QEMU
``-M mps2-an385``: the MPS2 board with the AN385 image, the memory map and CMSDK UART of the
mps2-an386) and the Cortex-M0 (``arm-none-eabi-cortex-m0.cmake``, QEMU ``-M microbit``: an
nRF51822, 256 KiB of flash and 16 KiB of RAM), both without an FPU. Golden vectors generated
here (every method x feedforward x anti-windup, random drives and scalings; random, stepped and
extreme speeds, applied torques other than the controller's own, resets) run through the Q15
and the Q31 controller on each emulated core (``csrc/target/target_fixed_vectors.c``) and on the
host through ``pmsm2dof._core``: every coefficient after init (computed in double: software
floating point on the MCUs, SSE2 on the host, both IEEE 754 with correct rounding) and every
output and state word after every operation must be equal. The steps themselves use no floating
point: nothing they reach in the linked program is a floating-point routine.

Without the cross toolchain or QEMU the tests are skipped, each with the reason.
"""

import re
import subprocess

import numpy as np
import pytest
from test_target_qemu import CSRC, QEMU_TIMEOUT_S, needs_cross, needs_qemu, run

from pmsm2dof.core import ANTI_WINDUPS, FEEDFORWARDS, METHODS
from pmsm2dof.core.bindings import ffi, lib
from pmsm2dof.core.fixedpoint import GAINS, FixedPointSpeedController
from pmsm2dof.errors import ConfigError

#: Slow (builds, emulators, fuzzing, browsers or whole reproductions): run by the full suite.
pytestmark = [pytest.mark.slow, needs_cross, needs_qemu]

SAMPLES = 100
QEMU_ARGS = ["-nographic", "-semihosting-config", "enable=on,target=native"]
#: core: (toolchain file, QEMU machine, the Arm architecture in the build attributes)
CORES = {
    "cortex-m3": ("arm-none-eabi-cortex-m3.cmake", "mps2-an385", "v7"),
    "cortex-m0": ("arm-none-eabi-cortex-m0.cmake", "microbit", "v6S-M"),
}
OUTPUT_FIELDS = ("w_ref", "e", "T_ff", "y_ff", "T_unsat", "T_ref", "iq_ref", "saturated")
#: 64-bit fields of the Q31 rows (two words each, high first)
WIDE = {"e", "T_ff", "y_ff", "T_unsat", "x", "y_prev"}
#: the 64-bit integer routines of the Arm run-time ABI a step may call on a core without them
INTEGER_HELPERS = re.compile(r"__aeabi_(u?lmul|llsl|llsr|lasr|u?lcmp|u?ldivmod)$")


def f32(x):
    return float(np.float32(x))


def config(rng, method, ff, aw):
    """A surface PMSM from a small servo to an industrial drive, at 1 to 10 kHz, scaled to 2 to 8 times its
    torque limit and to 2^-4 to 2^6 times the speed at which the proportional gain makes one full scale."""
    while True:
        J, alpha, Ts = 10 ** rng.uniform(-4, 0), 10 ** rng.uniform(0, 2.5), rng.choice([1e-4, 2.5e-4, 1e-3])
        psi_f, pole_pairs, i_max = rng.uniform(0.02, 0.4), int(rng.integers(1, 8)), rng.uniform(1.0, 30.0)
        T_max = 1.5 * pole_pairs * psi_f * i_max
        T_fs = T_max * rng.uniform(2.0, 8.0)
        cfg = dict(
            J_kgm2=f32(J),
            alpha_radps=f32(alpha),
            zeta=f32(rng.uniform(0.3, 1.5)),
            m=1.0 if ff == "lowpass" else f32(rng.uniform(0.5, 3.0)),
            tau_i_s=f32(Ts * rng.uniform(2.0, 20.0)),
            Ka=f32(rng.uniform(0.3, 3.0) / (J * alpha)),
            Ts_s=f32(Ts),
            i_max_A=f32(i_max),
            psi_f_Wb=f32(psi_f),
            Ld_H=f32(1e-3),
            Lq_H=f32(1e-3),
            pole_pairs=pole_pairs,
            method=method,
            feedforward=ff,
            anti_windup=aw,
            speed_full_scale_radps=f32(T_fs / (J * alpha) * 2.0 ** rng.uniform(-4, 6)),
            torque_full_scale_Nm=f32(T_fs),
            current_full_scale_A=f32(i_max * rng.uniform(1.0, 3.0)),
        )
        try:
            FixedPointSpeedController("q15", **cfg)
            FixedPointSpeedController("q31", **cfg)
        except ConfigError:
            continue
        return cfg


def operations(rng, bits):
    """(SAMPLES, 4) ints {op, w_ref, w_m, a}: op 0 a step, 1 compute and update with the applied torque a,
    2 a reset to (w_ref, a); speeds stepping across the range with a lagging measurement, extremes."""
    top = 2**bits
    w_ref = np.repeat(rng.integers(-top, top, 5), SAMPLES // 5)
    w_m = np.zeros(SAMPLES, dtype=np.int64)
    for k in range(1, SAMPLES):
        w_m[k] = w_m[k - 1] + (w_ref[k - 1] - w_m[k - 1]) // 4
    w_m = np.clip(w_m + rng.integers(-top // 64, top // 64, SAMPLES), -top, top - 1)
    op = np.where(rng.uniform(size=SAMPLES) < 0.25, 1, 0)
    a = rng.integers(-top, top, SAMPLES)
    # extremes: a reversal from end to end, the ends of the applied torque, a reset
    w_ref[40:44], w_m[40:44] = top - 1, -top
    w_ref[44:48], w_m[44:48] = -top, top - 1
    op[46], a[46] = 1, -top
    op[47], a[47] = 1, top - 1
    op[70], a[70] = 2, rng.integers(-top // 2, top // 2)
    return np.stack([op, w_ref, w_m, a], axis=1)


@pytest.fixture(scope="module")
def vectors():
    rng = np.random.default_rng(20261201)
    cases = [config(rng, me, ff, aw) for me in METHODS for ff in FEEDFORWARDS for aw in ANTI_WINDUPS]
    return dict(cases=cases, q15=[operations(rng, 15) for _ in cases], q31=[operations(rng, 31) for _ in cases])


def c_literal(value):
    if isinstance(value, str):
        return value
    if isinstance(value, int):
        return f"{value}"
    return f"{float(value).hex()}f"


def vectors_header(v):
    """Text of p2d_fixed_vectors.h (csrc/target/target_fixed_vectors.c)."""
    enums = dict(method=("P2D_", METHODS), feedforward=("P2D_FF_", FEEDFORWARDS), anti_windup=("P2D_AW_", ANTI_WINDUPS))
    scalings = ("speed_full_scale_radps", "torque_full_scale_Nm", "current_full_scale_A")

    def config_text(cfg):
        speed = ", ".join(
            f".{k} = {enums[k][0] + v.upper() if k in enums else c_literal(v)}"
            for k, v in cfg.items()
            if k not in scalings
        )
        return "{.speed = {" + speed + "}, " + ", ".join(f".{k} = {c_literal(cfg[k])}" for k in scalings) + "}"

    def ops(x, ctype):
        rows = ",\n".join("{" + ", ".join(f"({ctype}){int(w)}" for w in row) + "}" for row in x)
        return "{" + rows + "}"

    return "\n".join(
        [
            "/* written by tests/test_target_qemu_fixed.py */",
            f"#define P2D_FV_SAMPLES {SAMPLES}u",
            f"#define P2D_FV_CASES {len(v['cases'])}u",
            "static const p2d_speed_fixed_config_t p2d_fv_config[P2D_FV_CASES] = {",
            ",\n".join(config_text(c) for c in v["cases"]),
            "};",
            "static const int16_t p2d_fv_q15[P2D_FV_CASES][P2D_FV_SAMPLES][4] = {",
            ",\n".join(ops(x, "int16_t") for x in v["q15"]),
            "};",
            "static const int32_t p2d_fv_q31[P2D_FV_CASES][P2D_FV_SAMPLES][4] = {",
            # INT32_MIN as a literal is a negation of 2147483648, a long long: the cast brings it back
            ",\n".join(ops(x, "int32_t") for x in v["q31"]),
            "};",
            "",
        ]
    )


# --------------------------------------------------------------------------------------------
# host: the same C through pmsm2dof._core, printed as the target prints
# --------------------------------------------------------------------------------------------


def words(value, wide):
    """The words the target prints for an integer: one, or two (high, low) for a 64-bit field."""
    if wide:
        u = value & 0xFFFFFFFFFFFFFFFF
        return [u >> 32, u & 0xFFFFFFFF]
    return [value & 0xFFFFFFFF]


def host_rows(fmt, cfg, ops):
    """(status, coefficient words, [(k, words)]) of one case on the host."""
    c_cfg = FixedPointSpeedController._c_config(cfg)
    ctl = ffi.new(f"p2d_speed_{fmt}_t *")
    status = getattr(lib, f"p2d_speed_{fmt}_init")(ctl, c_cfg)
    if status != 0:
        return status, None, []
    k = ctl.coef[ctl.active]
    coef = []
    for name in GAINS:
        coef += [getattr(k, name).mantissa & 0xFFFFFFFF, getattr(k, name).shift]
    coef += [getattr(k, f"T_max_{fmt}") & 0xFFFFFFFF, getattr(k, f"iq_max_{fmt}") & 0xFFFFFFFF, int(k.clamping)]
    out = ffi.new(f"p2d_speed_{fmt}_output_t *")
    step, compute, update, reset = (
        getattr(lib, f"p2d_speed_{fmt}_{n}") for n in ("step", "compute", "update", "reset")
    )
    x_name = "x_q15" if fmt == "q15" else "x_q62"
    wide = fmt == "q31"
    rows = []
    for i, (op, w_ref, w_m, a) in enumerate(ops.tolist()):
        if op == 2:
            reset(ctl, w_ref, a)
            continue
        if op == 1:
            compute(ctl, w_ref, w_m, out)
            update(ctl, out, a)
        else:
            step(ctl, w_ref, w_m, out)
        row = []
        for name in OUTPUT_FIELDS:
            row += words(int(getattr(out, name if name == "saturated" else f"{name}_{fmt}")), wide and name in WIDE)
        row += words(int(getattr(ctl, x_name)), wide)
        row += words(int(getattr(ctl, f"y_ff_prev_{fmt}")), wide)
        row += words(int(getattr(ctl, f"r_prev_{fmt}")), False)
        rows.append((i, row))
    return status, coef, rows


def parse(text):
    """({(fmt, case): status}, {(fmt, case): coefficient words}, {(fmt, case, k): words}) of the target's output."""
    status, coef, rows = {}, {}, {}
    for line in text.splitlines():
        p = line.split()
        if p[:1] == ["I"]:
            status[(p[1].lower(), int(p[2], 16))] = int(p[3], 16)
        elif p[:1] == ["K"]:
            coef[(p[1].lower(), int(p[2], 16))] = [int(w, 16) for w in p[4:]]
        elif p[:1] in (["A"], ["B"]):
            rows[("q15" if p[0] == "A" else "q31", int(p[1], 16), int(p[2], 16))] = [int(w, 16) for w in p[3:]]
    return status, coef, rows


@pytest.fixture(scope="module", params=sorted(CORES))
def core_build(request, tmp_path_factory, vectors):
    """(core, build folder) of the cross build of one core with the golden-vector runner."""
    core = request.param
    toolchain = CSRC / "cmake" / CORES[core][0]
    tmp = tmp_path_factory.mktemp(core)
    (tmp / "p2d_fixed_vectors.h").write_text(vectors_header(vectors))
    build = tmp / "build"
    run(["cmake", "-S", CSRC, "-B", build, f"-DCMAKE_TOOLCHAIN_FILE={toolchain}", f"-DP2D_FIXED_VECTORS_DIR={tmp}"])
    run(["cmake", "--build", build, "-j2", "--target", "p2d_fixed_vectors", "p2d_fixed_cost"])
    return core, build


def test_library_builds_for_the_core_without_an_fpu(core_build):
    core, build = core_build
    attributes = run(["arm-none-eabi-readelf", "-A", build / "libpmsm2dof_controller.a"])
    members = run(["arm-none-eabi-ar", "t", build / "libpmsm2dof_controller.a"]).split()
    assert sorted(members) == sorted(f"{p.name}.obj" for p in (CSRC / "src").glob("*.c"))
    assert attributes.count(f"Tag_CPU_arch: {CORES[core][2]}") == len(members)
    assert "Tag_FP_arch" not in attributes and "Tag_ABI_HardFP_use" not in attributes


def test_golden_vectors_equal_the_host_to_the_bit(core_build, vectors):
    core, build = core_build
    machine = CORES[core][1]
    done = subprocess.run(
        ["qemu-system-arm", "-M", machine, *QEMU_ARGS, "-kernel", str(build / "target" / "p2d_fixed_vectors")],
        capture_output=True,
        text=True,
        timeout=QEMU_TIMEOUT_S,
        stdin=subprocess.DEVNULL,
    )
    # semihosting output arrives on stderr
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stderr.splitlines()[-1] == "END"
    status, coef, rows = parse(done.stderr)
    mismatches, saturated, compared, n_rows = [], {"q15": 0, "q31": 0}, 0, 0
    for fmt in ("q15", "q31"):
        for c, (cfg, ops) in enumerate(zip(vectors["cases"], vectors[fmt])):
            host_status, host_coef, host = host_rows(fmt, cfg, ops)
            assert host_status == 0 and status[(fmt, c)] == 0, (fmt, c, host_status, status.get((fmt, c)), cfg)
            if coef[(fmt, c)] != host_coef:
                mismatches.append(f"{fmt} case {c} coefficients: target {coef[(fmt, c)]}, host {host_coef}")
            n_rows += len(host)
            for k, row in host:
                target = rows[(fmt, c, k)]
                compared += len(row)
                if target != row:
                    mismatches.append(f"{fmt} case {c} sample {k}: target {target}, host {row} ({cfg})")
                saturated[fmt] += row[11 if fmt == "q31" else 7]  # the words before it: 64-bit e, T_ff, y, u
    assert not mismatches, (
        f"{core}: {len(mismatches)} rows differ (is pmsm2dof._core older than csrc/src? rebuild it):\n"
        + "\n".join(mismatches[:10])
    )
    assert len(rows) == n_rows
    print(
        f"\n{core} ({machine}): {len(vectors['cases'])} cases x 2 formats, {compared} words equal; "
        f"saturated {saturated}"
    )
    assert min(saturated.values()) > 100


def call_graph(elf):
    """{function: set of functions it branches to} from the disassembly of the ELF."""
    calls, current = {}, None
    for line in run(["arm-none-eabi-objdump", "-d", "--no-show-raw-insn", elf]).splitlines():
        head = re.match(r"^[0-9a-f]+ <(.+)>:$", line)
        if head:
            current = head.group(1)
            calls[current] = set()
            continue
        target = re.search(r"^\s*[0-9a-f]+:\s+(b\S*)\s.*<([^>+]+)>", line)
        if target and current is not None and target.group(2) != current:
            calls[current].add(target.group(2))
    return calls


def test_the_steps_use_integers_only(core_build):
    """From p2d_speed_q15_step and p2d_speed_q31_step the linked program reaches only the controller's own
    functions and the run-time ABI's 64-bit integer routines (the M0 multiplies 64-bit numbers in software)."""
    _, build = core_build
    calls = call_graph(build / "target" / "p2d_fixed_cost")
    for root in ("p2d_speed_q15_step", "p2d_speed_q31_step"):
        seen, todo = set(), [root]
        while todo:
            f = todo.pop()
            if f not in seen:
                seen.add(f)
                todo.extend(calls.get(f, ()))
        foreign = {f for f in seen if f.startswith("__") and not INTEGER_HELPERS.match(f)}
        assert not foreign, (root, sorted(seen))
        assert all(f.startswith("p2d_") or INTEGER_HELPERS.match(f) for f in seen), (root, sorted(seen))
