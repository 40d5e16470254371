"""What importing pmsm2dof costs: the heavy libraries load only when a feature needs them.

``import pmsm2dof`` and ``pmsm2dof --help`` must not import python-control, matplotlib,
scipy.signal, pandas or dask (PEP 562 ``__getattr__`` in ``pmsm2dof/__init__.py``, imports
inside the CLI commands); each check runs in a fresh interpreter and reads ``sys.modules``.
"""

import subprocess
import sys

import pytest

import pmsm2dof

HEAVY = ("control", "matplotlib", "scipy.signal", "pandas", "dask")

PROBE = """
import sys
{code}
print("loaded:" + ",".join(m for m in {heavy!r} if m in sys.modules))
"""


def loaded_after(code):
    """The heavy modules in ``sys.modules`` after running ``code`` in a fresh interpreter."""
    run = subprocess.run(
        [sys.executable, "-c", PROBE.format(code=code, heavy=HEAVY)], capture_output=True, text=True, timeout=120
    )
    assert run.returncode == 0, run.stderr
    (line,) = [line for line in run.stdout.splitlines() if line.startswith("loaded:")]
    return [m for m in line[len("loaded:") :].split(",") if m]


@pytest.mark.parametrize(
    "code",
    [
        "import pmsm2dof",
        "from pmsm2dof.ui.cli import main\ntry:\n    main(['--help'])\nexcept SystemExit:\n    pass",
        "from pmsm2dof.ui.cli import main\nmain(['presets'])",
        "import pmsm2dof\n"
        "pmsm2dof.simulate, pmsm2dof.load_scenario, pmsm2dof.compute_metrics, pmsm2dof.SpeedController",
    ],
)
@pytest.mark.slow
def test_importing_and_help_load_no_heavy_library(code):
    assert loaded_after(code) == []


@pytest.mark.slow
def test_the_design_loads_python_control_when_used():
    """The probe sees a heavy import when there is one (a check that can fail): a transfer function of
    the design is python-control's."""
    assert "control" in loaded_after("import pmsm2dof\npmsm2dof.design(0.4, 10.0, 0.7).Gx")


def test_every_public_name_resolves_and_is_listed():
    assert set(pmsm2dof.__all__) <= set(dir(pmsm2dof))
    for name in pmsm2dof.__all__:
        assert getattr(pmsm2dof, name) is not None
    with pytest.raises(AttributeError, match="no attribute 'nothing'"):
        pmsm2dof.nothing  # noqa: B018
