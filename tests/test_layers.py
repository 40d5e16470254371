"""The import direction of the layers, and the names the library's errors use.

The contracts are import-linter's (``[tool.importlinter]`` in pyproject.toml): ``ui`` ->
``studies`` -> ``sim`` | ``analysis`` -> ``core`` -> ``outputs`` | ``inputs`` -> ``errors``, imports pointing
down only, ``sim`` and ``analysis`` not importing each other, no import cycle between the modules
of a package, and no module importing the package's lazy facade ``pmsm2dof/__init__.py``.

That the check can fail is shown on a copy of the package with one wrong import added: an upward
import, a sibling import, a cycle and an import of the facade each break a contract.
"""

import ast
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "src" / "pmsm2dof"
#: ``lint-imports`` run by this interpreter (a venv with system site-packages has no script of its own).
LINT_IMPORTS = [sys.executable, "-c", "from importlinter.cli import lint_imports_command; lint_imports_command()"]


def lint_imports(source_root):
    """``lint-imports`` with the project's contracts on the package found in ``source_root``."""
    env = dict(os.environ, PYTHONPATH=str(source_root))
    return subprocess.run(
        [*LINT_IMPORTS, "--config", str(ROOT / "pyproject.toml"), "--no-cache"],
        cwd=source_root,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )


def test_the_layers_keep_their_import_contracts():
    run = lint_imports(ROOT / "src")
    assert run.returncode == 0, run.stdout + run.stderr
    assert "3 kept, 0 broken" in run.stdout


@pytest.mark.parametrize(
    "module, line, broken",
    [
        ("core/controllers.py", "from ..ui import cli", "layers"),  # upward
        ("sim/metrics.py", "from ..analysis import margins", "layers"),  # between the independent siblings
        ("analysis/discretize.py", "from . import design", "no import cycles"),  # design imports discretize
        ("sim/metrics.py", "from .. import design", "public names"),  # the facade, not a module
    ],
)
def test_a_wrong_import_breaks_a_contract(tmp_path, module, line, broken):
    copy = tmp_path / "src"
    shutil.copytree(PACKAGE, copy / "pmsm2dof", ignore=shutil.ignore_patterns("*.so", "__pycache__"))
    path = copy / "pmsm2dof" / module
    path.write_text(path.read_text() + f"\n{line}\n")
    run = lint_imports(copy)
    assert run.returncode != 0
    assert f"{broken}" in run.stdout and "BROKEN" in run.stdout, run.stdout


def _modules():
    return sorted(PACKAGE.rglob("*.py"))


def test_only_the_bindings_import_the_compiled_extension():
    importers = []
    for path in _modules():
        for node in ast.walk(ast.parse(path.read_text())):
            names = []
            if isinstance(node, ast.ImportFrom):
                names = [node.module or ""] + [f"{node.module or ''}.{a.name}" for a in node.names]
            elif isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            if any(name.split(".")[-1] == "_core" for name in names):
                importers.append(path.relative_to(PACKAGE).as_posix())
    assert importers == ["core/bindings.py"]


def test_library_errors_name_parameters_not_command_line_flags():
    """Only the user interface knows the flags: below it a ConfigError names a parameter or a key."""
    flags = []
    for path in _modules():
        if path.relative_to(PACKAGE).parts[0] == "ui":
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if (
                isinstance(node, ast.Call)
                and getattr(node.func, "id", None) == "ConfigError"
                and node.args
                and isinstance(node.args[0], ast.Constant)
                and str(node.args[0].value).startswith("-")
            ):
                flags.append(f"{path.relative_to(PACKAGE)}:{node.lineno}: {node.args[0].value}")
    assert flags == []
