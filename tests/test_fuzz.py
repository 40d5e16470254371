"""Bounded fuzzing of the C controllers, filters and estimator with libFuzzer under ASan and UBSan.

The targets csrc/fuzz/fuzz_speed.c, fuzz_speed_fixed.c (the Q15 and Q31
controllers), fuzz_current.c, fuzz_commission.c, fuzz_encoder.c,
fuzz_field_weakening.c, fuzz_inertia.c and fuzz_filter.c decode
random configurations and input sequences and abort on any violated invariant
(output finite and within I_max or u_dc/sqrt(3), integrator bounds under back
calculation and clamping, the anti-windup update through the torque filters,
counter increments and estimator bounds, atomic parameter updates, filters that
realize their design and hold a constant input exactly, no poisoned state; the
commissioning routine's phases, its trip, and estimates that match the motor
when it ends; the inertia estimator's covariance within its prior and its
outputs within their bounds; the fixed-point controllers' signals within two
full scales, their integrators' rounding at the dead zone's edges and one LSB
of Q31 error, and under UBSan no shift of a negative number and no overflow;
see RELIABILITY.md). Each runs for a bounded time
from a copy of the checked-in seed corpus; the executions are printed (pytest
-s shows them).

Mutants of the controllers, the torque filters, the estimators and the
commissioning routine (the non-finite policy of the update removed, clamping
that never holds, a voltage limit that is never active, a speed controller that
limits the unfiltered command, a filter whose overflowing state is not refused,
no overcurrent trip, a NaN current let through, an encoder increment read
unsigned, an unlimited field-weakening current, a field-weakening torque limit
that ignores the d current; the inertia estimator's non-finite policy removed,
its forgetting without the bound of the prior, its output without the bound of
J_max; a Q31 integrator deaf to one LSB of error, a Q15 feedforward transient
not held within two full scales, Q15 clamping that never holds) show that the
invariants catch real faults: each is caught by replaying
the seed corpus alone.

Each target executes a fixed number of inputs from libFuzzer seed 1 (FUZZ_RUNS) without comparison tracing
(-use_cmp=0: the operands libFuzzer records include addresses, which address-space randomisation changes from
run to run, so with it two runs from one seed diverge); every run then executes the same inputs.
P2D_FUZZ_SECONDS=N fuzzes for N seconds per target instead, with comparison tracing.
"""

import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest

#: Slow (builds, emulators, fuzzing, browsers or whole reproductions): run by the full suite.
pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parent.parent
CSRC = ROOT / "csrc"
CORPUS = CSRC / "fuzz" / "corpus"
#: Executions of each target: a fixed number from a fixed seed, so that every run executes the same inputs
#: whatever the machine's speed (about 15 s each on one x86-64 core of 2026).
FUZZ_RUNS = {
    "speed": 80_000,
    "speed_fixed": 20_000,
    "current": 110_000,
    "commission": 6_000,
    "encoder": 100_000,
    "field_weakening": 48_000,
    "inertia": 60_000,
    "filter": 110_000,
    "xcp": 50_000,
}
#: Exploration instead: P2D_FUZZ_SECONDS=N fuzzes each target for N seconds (with P2D_FUZZ_SEED=0, from a seed
#: libFuzzer picks).
FUZZ_SECONDS = os.environ.get("P2D_FUZZ_SECONDS")
FUZZ_SEED = int(os.environ.get("P2D_FUZZ_SEED", "1"))
SANITIZE = ["-fsanitize=fuzzer,address,undefined", "-fno-sanitize-recover=all", "-g", "-O1"]
TARGETS = ("speed", "speed_fixed", "current", "commission", "encoder", "field_weakening", "inertia", "filter", "xcp")


def _libfuzzer_missing(tmp_path):
    """Why libFuzzer cannot be used here, or None when it can."""
    if shutil.which("clang") is None:
        return "clang is not installed (Debian: apt-get install clang libclang-rt-14-dev)"
    if shutil.which("cmake") is None:
        return "cmake is not installed"
    probe = tmp_path / "probe.c"
    probe.write_text(
        "#include <stddef.h>\n#include <stdint.h>\n"
        "int LLVMFuzzerTestOneInput(const uint8_t *d, size_t n) { (void)d; (void)n; return 0; }\n"
    )
    result = subprocess.run(
        ["clang", *SANITIZE, str(probe), "-o", str(tmp_path / "probe")], capture_output=True, text=True
    )
    if result.returncode != 0:
        return "clang cannot link libFuzzer with ASan/UBSan (Debian: libclang-rt-14-dev): " + result.stderr[-300:]
    return None


@pytest.fixture(scope="module")
def fuzz_build(tmp_path_factory):
    """A P2D_FUZZ build of csrc (clang, RelWithDebInfo) in a temporary folder."""
    missing = _libfuzzer_missing(tmp_path_factory.mktemp("probe"))
    if missing:
        pytest.skip(missing)
    build = tmp_path_factory.mktemp("fuzz-build")
    for command in (
        [
            "cmake",
            "-S",
            str(CSRC),
            "-B",
            str(build),
            "-DCMAKE_C_COMPILER=clang",
            "-DP2D_FUZZ=ON",
            "-DCMAKE_BUILD_TYPE=RelWithDebInfo",
        ],
        ["cmake", "--build", str(build), "--target", *(f"fuzz_{t}" for t in TARGETS), "-j", "2"],
    ):
        result = subprocess.run(command, capture_output=True, text=True)
        assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    return build


def _stats(stderr):
    """(executions, seconds, exec/s, corpus units) from libFuzzer's final lines."""
    done = re.search(r"^#(\d+)\s+DONE\s.*?corp: (\d+)/.*?exec/s: (\d+)", stderr, re.M)
    runs = re.search(r"^Done (\d+) runs in (\d+) second", stderr, re.M)
    assert done and runs, "no libFuzzer DONE line:\n" + stderr[-3000:]
    return int(runs.group(1)), int(runs.group(2)), int(done.group(3)), int(done.group(2))


def _bounded(runs):
    """libFuzzer's options for ``runs`` executions that every run repeats (module docstring)."""
    return [f"-runs={runs}", "-use_cmp=0"]


def _fuzz(fuzz_build, target, tmp_path, bound):
    """Run one target on a copy of its seed corpus, within ``bound`` (libFuzzer options)."""
    corpus = tmp_path / "corpus"
    shutil.copytree(CORPUS / target, corpus)
    return subprocess.run(
        [
            str(fuzz_build / f"fuzz_{target}"),
            str(corpus),
            *bound,
            f"-seed={FUZZ_SEED}",
            "-timeout=30",
            "-rss_limit_mb=2048",
            "-print_final_stats=1",
            f"-artifact_prefix={tmp_path}/",
        ],
        capture_output=True,
        text=True,
        timeout=4 * int(FUZZ_SECONDS or 60) + 120,
    )


@pytest.mark.parametrize("target", TARGETS)
def test_fuzz_target_bounded_run(fuzz_build, target, tmp_path):
    seeds = len(list((CORPUS / target).iterdir()))
    assert seeds > 0
    bound = [f"-max_total_time={FUZZ_SECONDS}"] if FUZZ_SECONDS else _bounded(FUZZ_RUNS[target])
    result = _fuzz(fuzz_build, target, tmp_path, bound)
    assert result.returncode == 0, f"fuzz_{target} found a failure:\n" + result.stderr[-6000:]
    executions, seconds, rate, units = _stats(result.stderr)
    print(
        f"\nfuzz_{target}: {executions} executions in {seconds} s ({rate} exec/s), "
        f"corpus {seeds} seeds -> {units} units"
    )
    assert executions > seeds


def test_bounded_runs_repeat_exactly(fuzz_build, tmp_path):
    """Two bounded runs of one target from one seed reach the same coverage, features and corpus: CI executes
    the inputs a local run executed (the commissioning target, whose state machine branches most)."""
    finals = []
    for run in ("a", "b"):
        (tmp_path / run).mkdir()
        result = _fuzz(fuzz_build, "commission", tmp_path / run, _bounded(3000))
        assert result.returncode == 0, result.stderr[-3000:]
        finals.append(re.search(r"^#\d+\s+DONE\s+(cov: \d+ ft: \d+ corp: \d+/\S+)", result.stderr, re.M).group(1))
    assert finals[0] == finals[1]


# name: (fuzz target, controller source, [(original text, mutated text), ...])
MUTANTS = {
    # the non-finite policy of the update is gone: a NaN applied torque enters the integrator
    "speed_nan_state": (
        "speed",
        "speed.c",
        [("if (out->fault || !isfinite(T_applied_Nm)) {", "if (out->fault) {"), ("if (!isfinite(x)) {", "if (0) {")],
    ),
    # clamping never holds the integrator: it winds up while the torque is saturated (the PI block of both
    # controllers, caught by the speed controller's invariants)
    "speed_no_clamping": (
        "speed",
        "pi.h",
        [
            (
                "if (clamping && p2d_opposite_signs(u_star, e)) dx = 0.0f;",
                "if (clamping && p2d_opposite_signs(u_star, e)) dx = dx;",
            )
        ],
    ),
    # the voltage limit never cuts the q axis: the vector leaves the circle
    "current_no_limit": (
        "current",
        "current_step.h",
        [("out->uq_ref_V = uq > uq_max ? uq_max : (uq < -uq_max ? -uq_max : uq);", "out->uq_ref_V = uq;")],
    ),
    # the commissioning routine never trips: a current that runs away goes on
    "commission_no_trip": (
        "commission",
        "commission.c",
        [("if (fmaf(id_A, id_A, iq_A * iq_A) > c->config.i_trip_A * c->config.i_trip_A) {", "if (0) {")],
    ),
    # a NaN current passes into the commissioning routine
    "commission_nan_current": (
        "commission",
        "commission.c",
        [("if (!isfinite(id_A) || !isfinite(iq_A) || !isfinite(u_dc_V)) {", "if (!isfinite(u_dc_V)) {")],
    ),
    # the speed controller's compute limits the unfiltered command while it reports the filtered one
    "speed_limit_before_filters": (
        "speed",
        "speed.c",
        [
            (
                "if (c->filtered) u = filtered_compute(ctl, u, out);",
                "if (c->filtered) (void)filtered_compute(ctl, u, out);",
            )
        ],
    ),
    # an overflow of a filter state is not refused: it poisons the filter
    "filter_nan_state": (
        "filter",
        "filter.c",
        [("if (!isfinite(y) || !p2d_filter_state_finite(c, &next)) {", "if (!isfinite(y)) {")],
    ),
    # the estimator takes NaN and inf in, and keeps what overflows
    "inertia_nan_state": (
        "inertia",
        "inertia.c",
        [
            ("if (!isfinite(w_m_radps) || !isfinite(T_e_Nm)) {", "if (0) {"),
            ("if (!isfinite(wF) ||", "if (0 && (!isfinite(wF) ||"),
            ("!isfinite(residual_sd)) {", "!isfinite(residual_sd))) {"),
        ],
    ),
    # no variance is brought back onto its prior: the covariance winds up without excitation
    "inertia_windup": ("inertia", "inertia.c", [("if (P <= sd0 * sd0) {", "if (1) {")]),
    # the output of J is not limited to [J_min, J_max]
    "inertia_no_output_limit": (
        "inertia",
        "inertia.c",
        [("out->J_kgm2 = clamp(J, c->J_min_kgm2, c->J_max_kgm2);", "out->J_kgm2 = J;")],
    ),
    # the counter increment is not read as a signed number: a step back wraps to a huge forward one
    "encoder_no_wrap": (
        "encoder",
        "encoder.c",
        [("dn = d >= c->counter_half ? -(int32_t)(c->counter_mask - d) - 1 : (int32_t)d;", "dn = (int32_t)d;")],
    ),
    # the field weakening's output is not limited to [id_min, 0]
    "field_weakening_no_limit": ("field_weakening", "field_weakening.c", [("id = id_limited(c, v);", "id = v;")]),
    # the Q31 controller accepts a scaling whose integrator ignores one LSB of error (a dead zone)
    "speed_fixed_q31_deaf": (
        "speed_fixed",
        "speed_fixed.c",
        [("if (s > 31u && p2d_round_shift64(m, s - 31u) < 1) return P2D_ERR_SPEED_FULL_SCALE;", "(void)m;")],
    ),
    # the Q15 feedforward transient is not held within two full scales
    "speed_fixed_q15_y_unbounded": (
        "speed_fixed",
        "speed_q15.c",
        [
            (
                "q15_mul(c->ff_one_plus_a1, ctl->y_ff_prev_q15),\n                    Q15_SIGNAL_MAX);",
                "q15_mul(c->ff_one_plus_a1, ctl->y_ff_prev_q15),\n                    4 * Q15_SIGNAL_MAX);",
            )
        ],
    ),
    # Q15 clamping never holds the integrator
    "speed_fixed_q15_no_clamping": (
        "speed_fixed",
        "speed_q15.c",
        [("if (c->clamping && ((u_star < 0", "if (c->clamping && u_star < 0 && u_star > 0 && ((u_star < 0")],
    ),
    # the speed controller's field-weakening entry keeps the full torque limit: the current leaves the circle
    "speed_fw_full_limit": (
        "field_weakening",
        "speed.c",
        [("fw_torque_limit(c, id, iq_max), out)", "c->T_max_Nm, out)")],
    ),
    # the XCP slave takes an access that starts in a segment for inside it, wherever it ends
    "xcp_past_segment_end": (
        "xcp",
        "xcp.c",
        [
            (
                "address - s->address < s->size_bytes && n <= s->size_bytes - (address - s->address)",
                "address - s->address < s->size_bytes",
            )
        ],
    ),
    # a DOWNLOAD lands in the calibration segment at once, not on the shadow page
    "xcp_download_without_commit": (
        "xcp",
        "xcp.c",
        [
            (
                "copy_bytes((uint8_t *)x->config.shadow + (x->mta - s->address), cmd + 2, n);",
                "copy_bytes((uint8_t *)s->memory + (x->mta - s->address), cmd + 2, n);",
            )
        ],
    ),
    # a page the commit callback rejected is copied into the segment all the same
    "xcp_rejected_page_applied": (
        "xcp",
        "xcp.c",
        [
            (
                "if (code == 0) {\n        copy_bytes((uint8_t *)s->memory, (const uint8_t *)x->config.shadow, "
                "s->size_bytes);",
                "copy_bytes((uint8_t *)s->memory, (const uint8_t *)x->config.shadow, s->size_bytes);\n"
                "    if (code == 0) {",
            )
        ],
    ),
}

#: How a mutant is caught: a violated invariant of the target, or AddressSanitizer at a read or write of the guard
#: bytes around a segment (poisoned: "use-after-poison").
CAUGHT_BY = {"xcp_past_segment_end": "AddressSanitizer: use-after-poison"}


@pytest.mark.parametrize("mutant", sorted(MUTANTS))
def test_fuzz_invariants_catch_a_mutant(mutant, tmp_path):
    missing = _libfuzzer_missing(tmp_path)
    if missing:
        pytest.skip(missing)
    target, source, edits = MUTANTS[mutant]
    sources = []
    for path in sorted((CSRC / "src").glob("*.[ch]")):
        text = path.read_text()
        if path.name == source:
            for original, mutation in edits:
                assert text.count(original) == 1, f"the mutation anchor {original!r} is no longer in {path}"
                text = text.replace(original, mutation)
        copy = tmp_path / path.name
        copy.write_text(text)
        if path.suffix == ".c":
            sources.append(str(copy))
    binary = tmp_path / mutant
    build = subprocess.run(
        [
            "clang",
            *SANITIZE,
            "-I",
            str(CSRC / "include"),
            str(CSRC / "fuzz" / f"fuzz_{target}.c"),
            *sources,
            "-lm",
            "-o",
            str(binary),
        ],
        capture_output=True,
        text=True,
    )
    assert build.returncode == 0, build.stderr[-3000:]
    seeds = sorted(str(p) for p in (CORPUS / target).iterdir())
    result = subprocess.run(
        [str(binary), f"-artifact_prefix={tmp_path}/", *seeds], capture_output=True, text=True, timeout=120
    )
    caught_by = CAUGHT_BY.get(mutant, "pmsm2dof fuzz invariant violated")
    assert result.returncode != 0 and caught_by in result.stderr, result.stderr[-3000:]
