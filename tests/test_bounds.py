"""Every input that sets an amount of work or memory is bounded before the work starts.

The refusals run in one capped subprocess (the fast suite); the runs at a bound, the 2 GiB
compressed log, the streamed trace and the tuner's 400 MB body in the full suite.

Each probe runs the command in a subprocess whose address space is capped (``resource.setrlimit``)
at what it holds once its libraries are loaded plus a small budget, and with a timeout: a
regression that allocates or computes without bound fails here (MemoryError, a traceback, the
timeout) instead of swapping the machine. Each probe is one the issue found unbounded: a sensor
delay that grew a z^-n polynomial to 15 GB, a sweep of 1e9 points, a Bode list of 2000 values,
/dev/zero read whole, a compressed log of 3 GB, the log buffer of a long run, the CSV trace of a
long run held twice in memory, and a 400 MB body posted to the tuner.
"""

import json
import os
import subprocess
import sys
import textwrap
import zipfile

import httpx
import numpy as np
import pytest

#: Caps the address space at what the process holds after its imports plus BUDGET_MB.
CAP = textwrap.dedent(
    """
    import contextlib, io, json, os, resource, sys, traceback
    import control, matplotlib.pyplot, numpy, pandas, pyarrow.parquet, scipy.io, scipy.signal
    from pmsm2dof.ui.cli import main

    pandas.DataFrame({"a": [1.0]}).to_csv(io.StringIO())  # its first frame starts pandas' thread pools

    size = int(open("/proc/self/statm").read().split()[0]) * resource.getpagesize()
    budget = int(os.environ["BUDGET_MB"]) * 1024**2
    resource.setrlimit(resource.RLIMIT_AS, (size + budget, size + budget))
    """
)
#: Runs ``main(argv)``, capped (:data:`CAP`), for each argv of the JSON list in argv[1], and prints
#: ``[[exit status, stderr], ...]`` (an exception escaping main is a status "Traceback: ...").
CAPPED_MAIN = CAP + textwrap.dedent(
    """
    results = []
    for argv in json.loads(sys.argv[1]):
        err = io.StringIO()
        try:
            with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
                code = main(argv)
        except BaseException:
            code = "Traceback: " + traceback.format_exc()[-1500:]
        results.append([code, err.getvalue()])
    print(json.dumps(results))
    """
)


def run_capped(argvs, cwd, budget_mb=300, timeout_s=300):
    """``[(exit status, stderr)]`` of ``main(argv)`` for each of ``argvs``, in one capped subprocess."""
    env = dict(os.environ, BUDGET_MB=str(budget_mb), OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1")
    proc = subprocess.run(
        [sys.executable, "-c", CAPPED_MAIN, json.dumps(argvs)],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=timeout_s,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    return [tuple(r) for r in json.loads(proc.stdout.strip().splitlines()[-1])]


def assert_refused(result, *words):
    code, err = result
    assert code == 2, err[-2000:] if code != "Traceback" else code
    assert err.count("\n") == 1 and err.startswith("pmsm2dof: error: ") and "Traceback" not in err, err
    for word in words:
        assert word in err, err
    return err


DESIGN = ["design", "--J-kgm2", "0.4", "--alpha-radps", "0.5", "--zeta", "0.3", "--Ts-s", "1e-3"]
SWEEPS = {
    "num 1e9": ('"motor.J_kgm2" = { start = 0.1, stop = 1.0, num = 1000000000 }', "num = 1000000000"),
    "3000 x 3000": (
        '"motor.J_kgm2" = { start = 0.1, stop = 1.0, num = 3000 }\n'
        '"speed_controller.alpha_radps" = { start = 0.1, stop = 1.0, num = 3000 }',
        "'3000 x 3000 = 9000000 points'",
    ),
    "draws 1e9": ('"motor.J_kgm2" = { distribution = "uniform", low = 0.1, high = 1.0 }', "draws = 1000000000"),
}
FILES = [
    (["motor"], "/dev/zero"),
    (["motor"], "fifo"),
    (["motor"], "big.toml"),
    (["simulate", "--out", "o"], "/dev/zero"),
    (["commission"], "fifo"),
    (["sweep", "--out", "o"], "big.toml"),
]
#: Every refusal probe, by name: argv.
PROBES = {
    **{f"design --sensor-delay-s {d}": [*DESIGN, "--sensor-delay-s", d] for d in ("1e6", "10", "0.5", "0.257")},
    **{f"sweep {name}": ["sweep", f"{name.replace(' ', '_')}.toml", "--out", "out"] for name in SWEEPS},
    "bode --m 2000 values": ["bode", "--alpha-radps", "0.5", "--m", ",".join(["1"] * 2000), "--out", "f.png"],
    **{f"{command[0]} {path}": [command[0], path, *command[1:]] for command, path in FILES},
    "simulate t_end_s = 10000": ["simulate", "paper-condition-2", "--set", "simulation.t_end_s=10000", "--out", "long"],
}


@pytest.fixture(scope="module")
def refusals(tmp_path_factory):
    """Each probe's (exit status, stderr), run in one capped subprocess in a folder holding the files
    they read: a FIFO, a sparse 5 GiB file (no disk used) and the sweep files."""
    folder = tmp_path_factory.mktemp("probes")
    os.mkfifo(folder / "fifo")
    with open(folder / "big.toml", "wb") as f:
        f.truncate(5 * 1024**3)
    for name, (axes, _words) in SWEEPS.items():
        draws = "draws = 1000000000\nseed = 1\n" if "distribution" in axes else ""
        (folder / f"{name.replace(' ', '_')}.toml").write_text(f'base = "paper-condition-2"\n{draws}[axes]\n{axes}\n')
    before = sorted(p.name for p in folder.iterdir())
    results = dict(zip(PROBES, run_capped(list(PROBES.values()), folder)))
    assert sorted(p.name for p in folder.iterdir()) == before, "a refused command left something behind"
    return results


@pytest.mark.parametrize("delay_s", ["1e6", "10", "0.5", "0.257"])
def test_design_bounds_the_sensor_delay_in_periods(refusals, delay_s):
    """1e6 s grew to 15 GB, 10 s ran over 5 minutes, 0.5 s asked for 10 GiB of frequency responses."""
    assert_refused(refusals[f"design --sensor-delay-s {delay_s}"], "--sensor-delay-s = ", "<= 256 Ts_s = 0.256 s")


@pytest.mark.slow
def test_design_at_the_delay_bound_runs_within_the_budget(tmp_path):
    ((code, err),) = run_capped([[*DESIGN, "--sensor-delay-s", "0.256"]], tmp_path, budget_mb=400)
    assert code == 0, err[-2000:]


@pytest.mark.parametrize("name", SWEEPS)
def test_sweep_size_is_bounded_before_any_point_is_made(refusals, name):
    assert_refused(refusals[f"sweep {name}"], SWEEPS[name][1], "100000")


def test_bode_list_is_bounded(refusals):
    assert_refused(refusals["bode --m 2000 values"], "at most 20")


@pytest.mark.parametrize("command, path", FILES)
def test_input_files_are_regular_and_bounded(refusals, command, path):
    words = "a file of at most 4 MiB (it has 5 GiB)" if path == "big.toml" else "a regular file (it is a device"
    assert_refused(refusals[f"{command[0]} {path}"], words)


def test_the_log_of_a_long_run_that_does_not_fit_is_refused_with_its_size(refusals):
    """simulation.t_end_s = 10000 (the limit is 36000): its log buffer is refused with its size where
    it does not fit, instead of a MemoryError."""
    err = assert_refused(refusals["simulate t_end_s = 10000"], "simulation.log_every = 1", "10000001 rows need")
    assert "GiB" in err


@pytest.mark.slow
def test_a_compressed_log_is_bounded_by_what_it_holds(tmp_path):
    """A 3 MB NPZ that holds 2.2 GiB of zeros: refused from its headers, before it is inflated."""
    n = 2_300_000_000 // 8
    header = np.lib.format.header_data_from_array_1_0(np.zeros(1))
    header["shape"] = (n,)
    with zipfile.ZipFile(tmp_path / "log.npz", "w", zipfile.ZIP_DEFLATED, compresslevel=1) as z:
        with z.open("time_s.npy", "w", force_zip64=True) as f:
            np.lib.format.write_array_header_1_0(f, header)
            block = bytes(64 * 1024**2)
            for _ in range(n * 8 // len(block)):
                f.write(block)
            f.write(bytes(n * 8 % len(block)))
    assert (tmp_path / "log.npz").stat().st_size < 20 * 1024**2
    (result,) = run_capped([["identify", "mechanics", "log.npz", "--pole-pairs", "4", "--psi-f-Wb", "0.1"]], tmp_path)
    assert_refused(result, "(it holds 2.14 GiB)")


STREAM_SAVE = textwrap.dedent(
    """
    import io, os, resource, sys
    import numpy as np, pandas
    from pmsm2dof.sim.scenario import load_scenario
    from pmsm2dof.sim.simulate import simulate

    scenario = load_scenario("paper-experiment-1").with_overrides({"simulation.t_end_s": 1.0})
    result = simulate(scenario)
    n = int(os.environ["ROWS"])
    for name in result.signals:  # a long run's log, without running it: the rows repeated
        object.__setattr__(result, name, np.resize(getattr(result, name), n))
    pandas.DataFrame({"a": [1.0]}).to_csv(io.StringIO())  # its first frame starts pandas' thread pools
    size = int(open("/proc/self/statm").read().split()[0]) * resource.getpagesize()
    budget = int(os.environ["BUDGET_MB"]) * 1024**2
    resource.setrlimit(resource.RLIMIT_AS, (size + budget, size + budget))
    result.save(sys.argv[1])
    """
)


@pytest.mark.slow
def test_the_csv_trace_of_a_long_run_is_streamed_within_a_small_budget(tmp_path):
    """The log (0.9 M rows, about 190 MB) written as one CSV text needs about four times that
    (benchmarks/results.md); streamed, a budget of 150 MB above the log is enough."""
    rows = 900_000
    env = dict(os.environ, ROWS=str(rows), BUDGET_MB="150", OPENBLAS_NUM_THREADS="1")
    proc = subprocess.run(
        [sys.executable, "-c", STREAM_SAVE, str(tmp_path / "trace.csv")],
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    with open(tmp_path / "trace.csv") as f:
        assert f.readline().startswith("t_s,") and sum(1 for _ in f) == rows


TUNE = ["tune", "--port", "0", "--no-browser"]


@pytest.fixture(scope="module")
def capped_tuner(tmp_path_factory):
    """The tuner served by a subprocess with 300 MB of address space above its libraries."""
    env = dict(os.environ, BUDGET_MB="300", OPENBLAS_NUM_THREADS="1")
    proc = subprocess.Popen(
        [sys.executable, "-c", CAP + "sys.exit(main(sys.argv[1:]))\n", *TUNE],
        cwd=tmp_path_factory.mktemp("tune"),
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    line = proc.stdout.readline()
    url = line.split(" at ")[1].split()[0]
    yield url, proc
    proc.terminate()
    proc.communicate(timeout=60)


@pytest.mark.slow
@pytest.mark.parametrize("declared", [True, False], ids=["with its length", "chunked"])
def test_the_tuner_refuses_a_400_mb_body_without_reading_it_or_echoing_it(capped_tuner, declared):
    url, proc = capped_tuner
    size = 400 * 1024**2
    block = b'{"x": "' + b"a" * (1024**2 - 7)

    def body():
        yield block
        for _ in range(size // len(block) - 1):
            yield b"a" * len(block)

    headers = {"Content-Type": "application/json"}
    if declared:
        headers["Content-Length"] = str(size)
    try:
        response = httpx.post(url + "api/run", content=body(), headers=headers, timeout=60)
    except httpx.HTTPError as exc:  # the server answered and closed before all was sent
        pytest.fail(f"no answer: {exc!r}")
    assert response.status_code == 413 and len(response.content) < 300
    assert "longer than 65536 bytes" in response.json()["error"]
    assert proc.poll() is None
    ok = httpx.post(url + "api/run", json={}, timeout=60)
    assert ok.status_code == 200
