"""A module loaded on first use (pmsm2dof.lazy) is whole for every thread that reads it.

Under Python 3.11 the standard library's LazyLoader let a thread read the module while another
was executing it (CPython gh-114763): a sweep's threads running the sampled-loop check of a
scenario with a sensor chain failed with "module 'control' has no attribute 'tf'". A module that
takes 0.3 s to execute, read by eight threads at once, stands for python-control here.
"""

import json
import subprocess
import sys
import textwrap

READ_FROM_THREADS = textwrap.dedent(
    """
    import json, sys, threading
    sys.path.insert(0, sys.argv[1])
    from pmsm2dof.lazy import lazy_module

    slow = lazy_module("slow_module")
    before = "slow_module" in sys.modules
    errors, values = [], []

    def read():
        try:
            values.append(slow.value)
        except Exception as exc:
            errors.append(repr(exc))

    threads = [threading.Thread(target=read) for _ in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    print(json.dumps({"before": before, "errors": errors, "values": values, "runs": sys.modules["slow_module"].runs}))
    """
)


def test_threads_reading_a_module_while_it_loads_all_see_it_whole(tmp_path):
    (tmp_path / "slow_module.py").write_text("import time\n\ntime.sleep(0.3)\nvalue = 42\nruns = 1\n")
    proc = subprocess.run(
        [sys.executable, "-c", READ_FROM_THREADS, str(tmp_path)], capture_output=True, text=True, timeout=60
    )
    assert proc.returncode == 0, proc.stderr
    result = json.loads(proc.stdout)
    assert result["errors"] == [] and result["values"] == [42] * 8
    assert result["runs"] == 1  # executed once
    assert result["before"] is False  # not imported until an attribute is read
