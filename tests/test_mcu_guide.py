"""docs/mcu.md works as written: every fenced ``sh`` block, run verbatim from the repository root.

The blocks run with ``sh -e``, in order, in a fresh copy of ``csrc/`` and ``examples/`` (so the
build folders are new), as a user without an active virtual environment runs them: ``PATH``
holds the ``pmsm2dof`` command of this installation, a ``python3`` that lacks pmsm2dof ahead of
every other Python, and the system tools (cmake, make, the cross compiler, QEMU). The guide
promises the cross-built library, the configuration headers (of ``pmsm2dof header`` and of
``design``, the same shape), the firmware image built with that header, and the firmware built for
a scenario and run closed loop on QEMU in agreement with the engine; the firmware's build tree must
hold no folder that Python could import as ``pmsm2dof`` instead of the package.
"""

import json
import os
import re
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
GUIDE = ROOT / "docs" / "mcu.md"
TOOLS = ("cmake", "make", "arm-none-eabi-gcc", "qemu-system-arm", "sh")
BLOCK_TIMEOUT_S = 600

_MISSING = [t for t in TOOLS if shutil.which(t) is None]
#: Slow (cross builds and QEMU): run by the full suite.
pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(
        bool(_MISSING),
        reason=f"{', '.join(_MISSING)} not installed (Debian: cmake gcc-arm-none-eabi "
        "libnewlib-arm-none-eabi qemu-system-arm; scripts/install.sh installs them)",
    ),
]


def shell_blocks(text):
    return re.findall(r"^```sh\n(.*?)^```$", text, flags=re.M | re.S)


def user_environment(tmp_path):
    """The environment of a shell with no virtual environment active and a Python without pmsm2dof first."""
    installed = Path(sysconfig.get_path("scripts")) / "pmsm2dof"
    installed = installed if installed.is_file() else Path(shutil.which("pmsm2dof") or "")
    assert installed.is_file(), "the pmsm2dof command of this installation is not found"
    tool = tmp_path / "tool-bin"
    tool.mkdir()
    (tool / "pmsm2dof").symlink_to(installed)
    other = tmp_path / "other-python-bin"
    other.mkdir()
    for name in ("python3", f"python3.{sys.version_info.minor}", "python"):
        # the same interpreter without site-packages: a Python that has never seen pmsm2dof
        script = other / name
        script.write_text(f'#!/bin/sh\nexec "{sys.executable}" -S "$@"\n')
        script.chmod(0o755)
    system = [str(Path(shutil.which(t)).parent) for t in TOOLS] + ["/usr/bin", "/bin"]
    env = {
        k: v
        for k, v in os.environ.items()
        if k not in ("VIRTUAL_ENV", "PYTHONPATH", "PYTHONHOME", "CONDA_PREFIX") and not k.startswith("CMAKE_")
    }
    env["PATH"] = os.pathsep.join(dict.fromkeys([str(tool), str(other), *system]))
    return env


def test_other_python_cannot_import_pmsm2dof(tmp_path):
    env = user_environment(tmp_path)
    probe = subprocess.run(["python3", "-c", "import pmsm2dof"], env=env, cwd=tmp_path, capture_output=True, text=True)
    assert probe.returncode != 0 and "pmsm2dof" in probe.stderr


def test_every_shell_block_of_the_guide_runs_as_written(tmp_path):
    blocks = shell_blocks(GUIDE.read_text())
    assert len(blocks) >= 3, "the guide's commands are in ```sh blocks"
    repo = tmp_path / "repo"
    for folder in ("csrc", "examples"):
        shutil.copytree(ROOT / folder, repo / folder, ignore=shutil.ignore_patterns("build*", "__pycache__"))
    env = user_environment(tmp_path)
    for block in blocks:
        proc = subprocess.run(
            ["sh", "-e", "-c", block], cwd=repo, env=env, capture_output=True, text=True, timeout=BLOCK_TIMEOUT_S
        )
        assert proc.returncode == 0, f"{block}\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"

    assert (repo / "build-m4f" / "libpmsm2dof_controller.a").is_file()
    shapes = []
    for header in ("cfg", "cfg-design"):
        text = (repo / header / "p2d_config.h").read_text()
        assert "static const p2d_speed_config_t p2d_config_speed = {" in text
        shapes.append(re.findall(r"^(?:#define (\w+) |static const (\w+) (\w+) = )", text, flags=re.M))
    assert shapes[0] == shapes[1]
    assert (repo / "build-fw" / "firmware.elf").read_bytes().startswith(b"\x7fELF")
    assert not [p for p in (repo / "build-fw").rglob("pmsm2dof") if p.is_dir()]
    assert (repo / "fw-servo" / "virtual_drive.elf").read_bytes().startswith(b"\x7fELF")
    metrics = json.loads((repo / "run-servo" / "metrics.json").read_text())
    assert metrics["comparison"]["agrees"] is True
    assert metrics["interrupts"]["speed"]["interrupts"] == 401
    # pmsm2dof drive on the PC's drive: the capture (MDF4) and the run agreeing with the engine
    import asammdf

    with asammdf.MDF(repo / "capture.mf4") as mdf:
        assert len(mdf.get("foc_now.iq_A").samples) > 100
    assert json.loads((repo / "drive-run" / "metrics.json").read_text())["comparison"]["agrees"] is True
    # commissioning and identification on the drive of the servo without its load: its own motor's values
    servo = {"Rs_ohm": 0.5, "Ld_H": 5e-4, "Lq_H": 5e-4, "psi_f_Wb": 0.01}
    commissioned = json.loads((repo / "commissioned" / "result.json").read_text())
    assert commissioned["phase"] == "done" and (repo / "commissioned" / "motor.toml").is_file()
    for key, value in servo.items():
        assert commissioned["estimates"][key] == pytest.approx(value, rel=0.02), key
    assert json.loads((repo / "identified" / "identify.json").read_text())["J_kgm2"] == pytest.approx(1e-4, rel=0.02)
