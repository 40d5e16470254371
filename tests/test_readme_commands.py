"""The commands of the README and of the manual run as written and show what the text says they show.

The commands are read from README.md and the manual's pages (docs/, :data:`MANUAL`) themselves, so
the text cannot drift from the tool.
"""

import json
import re
import shlex
from pathlib import Path

import pytest

from pmsm2dof.ui.cli import main

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
#: The landing page and the pages of the manual whose commands run as written.
MANUAL = (
    README,
    *(
        ROOT / "docs" / page
        for page in ("getting-started.md", "design.md", "your-motor.md", "studies.md", "sensing.md", "development.md")
    ),
)


def manual_text():
    """The landing page and the manual's pages, one after the other."""
    return "\n".join(path.read_text() for path in MANUAL)


def readme_commands(program):
    """The ``program ...`` command lines of the ``sh`` blocks of the README and the manual: continuations
    joined, comments dropped, as argument lists without the program name."""
    commands = []
    for block in re.findall(r"```sh\n(.*?)```", manual_text(), flags=re.S):
        for line in block.replace("\\\n", " ").splitlines():
            args = shlex.split(line, comments=True)
            if args and args[0] == program:
                commands.append(args[1:])
    return commands


@pytest.mark.slow
def test_anti_windup_off_example_winds_up(tmp_path, monkeypatch):
    """Fig. 8 / claim C10: without anti-windup the speed overshoots by more than 55 %."""
    (args,) = [a for a in readme_commands("pmsm2dof") if "speed_controller.anti_windup=none" in a]
    monkeypatch.chdir(tmp_path)
    assert main(args) == 0
    out = tmp_path / args[args.index("--out") + 1]
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["reference_steps"][0]["overshoot_pct"]["value"] > 55.0


@pytest.mark.slow
def test_design_and_bode_commands_run_as_written(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    # design --motor reads the motor that the commissioning guide's command writes first: run there
    # (tests/test_readme_commissioning.py)
    commands = [a for a in readme_commands("pmsm2dof") if a[0] in ("design", "bode") and "--motor" not in a]
    assert {a[0] for a in commands} == {"design", "bode"}
    for args in commands:
        assert main(args) == 0, args
        captured = capsys.readouterr()
        for option in ("--emit-c-header", "--out"):
            if option in args:
                written = args[args.index(option) + 1]
                assert (tmp_path / written).stat().st_size > 0
                assert written in captured.out  # the command says what it wrote


@pytest.mark.slow
def test_autotune_commands_run_as_written(tmp_path, monkeypatch, capsys):
    """The Autotune section: each command ends with status 0 (a design meets its spec), writes what it
    says, and the Python example runs."""
    import shutil

    commands = [a for a in readme_commands("pmsm2dof") if a[0] == "autotune"]
    assert len(commands) == 2
    (tmp_path / "benchmarks").mkdir()
    shutil.copy(ROOT / "benchmarks" / "small-servo.toml", tmp_path / "benchmarks")
    monkeypatch.chdir(tmp_path)
    for args in commands:
        assert main(args) == 0, args
        captured = capsys.readouterr()
        if "--json" in args:
            data = json.loads(captured.out)
            assert data["feasible"] and data["worst_case"]["overshoot_pct"] <= 5.0
        if "--out" in args:
            out = tmp_path / args[args.index("--out") + 1]
            assert (out / "scenario.toml").stat().st_size > 0 and (out / "pareto.png").stat().st_size > 0
        if "--emit-c-header" in args:
            assert (tmp_path / args[args.index("--emit-c-header") + 1]).stat().st_size > 0
    (example,) = [b for b in re.findall(r"```python\n(.*?)```", manual_text(), flags=re.S) if "autotune" in b]
    exec(compile(example, "docs/studies.md", "exec"), {})
    assert "True {'alpha_radps'" in capsys.readouterr().out
