"""The package as users get it: the wheel, the sdist, and installs from a checkout.

Every build starts from a copy of the checkout's files as a fresh clone has them (tracked files
and new ones that are not ignored), with the commands of docs/development.md "Build backend": ``python -m build``
in an isolated build environment, as on a fresh machine. The wheel is installed into a new venv
without system site-packages (its dependencies come from the package index), by an install that
has no compiler: ``CC`` and ``CXX`` are ``false`` and ``PATH`` holds only the venv's scripts; a
control shows that cffi cannot compile there. From a folder outside the checkout that venv then
runs ``pmsm2dof reproduce``, whose claims and verdicts must be those of the table of docs/getting-started.md.
"""

import json
import os
import re
import shutil
import subprocess
import sys
import tarfile
import tomllib
import zipfile
from pathlib import Path

import pytest
from packaging.tags import sys_tags
from packaging.utils import parse_wheel_filename

#: Slow (builds, emulators, fuzzing, browsers or whole reproductions): run by the full suite.
pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[1]
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
#: The oldest CPython the package supports, from requires-python (">=3.N").
OLDEST_MINOR = int(re.fullmatch(r">=\s*3\.(\d+)", PYPROJECT["requires-python"])[1])
COMPILERS = ("cc", "gcc", "c++", "g++", "clang", "clang++")
#: Variables of the calling environment that would let it leak into the installs.
LEAKY = ("VIRTUAL_ENV", "PYTHONPATH", "PYTHONHOME", "PYTHONSTARTUP", "PYTHONUSERBASE", "CONDA_PREFIX")


def checkout_files():
    """The checkout's files as a fresh clone has them, plus new files not ignored (paths relative to ROOT)."""
    listed = subprocess.run(
        ["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
        cwd=ROOT,
        capture_output=True,
        check=True,
    ).stdout
    return sorted(name for name in os.fsdecode(listed).split("\0") if name and (ROOT / name).is_file())


def copy_checkout(dest):
    """Copy of the checkout's files (``checkout_files``) into ``dest``: no build products, no venv."""
    for name in checkout_files():
        (dest / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(ROOT / name, dest / name)
    return dest


def files_under(folder):
    return {p.relative_to(folder).as_posix() for p in folder.rglob("*") if p.is_file()}


def clean_env(**changes):
    """This process's environment less what points Python at the checkout or this venv."""
    env = {k: v for k, v in os.environ.items() if k not in LEAKY}
    env["PYTHONNOUSERSITE"] = "1"
    env.update(changes)
    return env


def run(cmd, timeout_s, **kwargs):
    """Run ``cmd``; on failure the assertion shows the command and the end of its output."""
    proc = subprocess.run([str(c) for c in cmd], capture_output=True, text=True, timeout=timeout_s, **kwargs)
    assert proc.returncode == 0, f"{cmd} exited {proc.returncode}:\n{(proc.stdout + proc.stderr)[-4000:]}"
    return proc.stdout


def build(srcdir, outdir, kind):
    """``python -m build --<kind>`` of ``srcdir`` (isolated build environment): the one file it made."""
    run([sys.executable, "-m", "build", f"--{kind}", "--outdir", outdir, srcdir], timeout_s=900)
    (made,) = Path(outdir).iterdir()
    return made


def wheel_names(wheel):
    with zipfile.ZipFile(wheel) as z:
        return set(z.namelist())


def package_files():
    """What the wheel must hold of the package: every file of src/pmsm2dof in a fresh clone."""
    return {name.removeprefix("src/") for name in checkout_files() if name.startswith("src/pmsm2dof/")}


@pytest.fixture(scope="module")
def wheel(tmp_path_factory):
    src = copy_checkout(tmp_path_factory.mktemp("checkout"))
    return build(src, tmp_path_factory.mktemp("dist"), "wheel")


def test_wheel_is_a_stable_abi_platform_wheel(wheel):
    """cp3N-abi3-<this platform>, with N the oldest Python of requires-python; the extension says abi3 too."""
    name, version, _, tags = parse_wheel_filename(wheel.name)
    assert (name, str(version)) == (PYPROJECT["name"], PYPROJECT["version"])
    (tag,) = tags
    assert (tag.interpreter, tag.abi) == (f"cp3{OLDEST_MINOR}", "abi3")
    assert tag.platform != "any" and tag in set(sys_tags()), tag
    with zipfile.ZipFile(wheel) as z:
        meta = z.read(f"pmsm2dof-{version}.dist-info/WHEEL").decode()
        extensions = [n for n in z.namelist() if n.endswith(".so") or n.endswith(".pyd")]
    assert "Root-Is-Purelib: false" in meta
    assert f"Tag: {tag}" in meta.splitlines()
    assert extensions == ["pmsm2dof/_core.abi3.so"]


def test_wheel_holds_the_package_data_and_nothing_else(wheel):
    """Every module, preset, tuner static file and py.typed, the compiled extension, and only those."""
    names = wheel_names(wheel)
    packaged = {n for n in names if ".dist-info/" not in n}
    expected = package_files() | {"pmsm2dof/_core.abi3.so"}
    assert packaged == expected
    for required in ("pmsm2dof/py.typed", "pmsm2dof/sim/presets/paper-condition-1.toml"):
        assert required in packaged
    assert any(n.startswith("pmsm2dof/ui/tuner/static/") for n in packaged)
    assert {n.split("/", 1)[1] for n in names if ".dist-info/" in n} >= {"METADATA", "RECORD", "entry_points.txt"}


#: Prints what the abi3 check needs of an interpreter: CPython, its minor, and no stable ABI (debug or free-threaded).
INTERPRETER = (
    "import sys, sysconfig\n"
    "no_abi3 = hasattr(sys, 'gettotalrefcount') or bool(sysconfig.get_config_var('Py_GIL_DISABLED'))\n"
    "print(sys.implementation.name, sys.version_info.minor, no_abi3)"
)
#: Calls into the extension: status texts (ints in, strings out) and the MTPA current (floats in and out).
CALLS = (
    "import json, pmsm2dof._core as c\n"
    "params = [c.ffi.string(c.lib.p2d_status_param(s)).decode() for s in range(c.lib.P2D_STATUS_COUNT)]\n"
    "id_A = [c.lib.p2d_mtpa_id_A(iq, 0.2, -0.004) for iq in (-7.6, 0.5, 7.6)]\n"
    "print(json.dumps([c.__file__, params, id_A]))"
)


def newer_cpythons():
    """Interpreters of CPython minors newer than this one (PATH, pyenv) that have the stable ABI."""
    root = Path(os.environ.get("PYENV_ROOT", "~/.pyenv")).expanduser()
    found = {}
    for minor in range(sys.version_info.minor + 1, 20):
        candidates = [shutil.which(f"python3.{minor}"), *sorted(root.glob(f"versions/3.{minor}*/bin/python3.{minor}"))]
        for exe in filter(None, candidates):
            probe = subprocess.run([exe, "-c", INTERPRETER], capture_output=True, text=True, timeout=60)
            if probe.returncode == 0 and probe.stdout.split() == ["cpython", str(minor), "False"]:
                found[minor] = exe
                break
    return found


def test_abi3_wheel_loads_on_newer_cpython(wheel, tmp_path):
    """The abi3 tag is honest: the one wheel's extension loads and computes the same on every newer CPython found."""
    interpreters = newer_cpythons()
    if not interpreters:
        pytest.skip(f"no CPython newer than 3.{sys.version_info.minor} found (PATH, pyenv)")
    _, *expected = json.loads(run([sys.executable, "-c", CALLS], timeout_s=120))
    for minor, exe in interpreters.items():
        venv = tmp_path / f"py3{minor}"
        run([exe, "-m", "venv", "--without-pip", venv], timeout_s=300)
        pip = [sys.executable, "-m", "pip", "--python", venv / "bin" / "python", "install", "-q"]
        run([*pip, "cffi"], timeout_s=600, env=clean_env())
        run([*pip, "--no-deps", wheel], timeout_s=600, env=clean_env())
        so, *computed = json.loads(run([venv / "bin" / "python", "-c", CALLS], 120, cwd=tmp_path, env=clean_env()))
        assert Path(so).is_relative_to(venv) and so.endswith("_core.abi3.so"), so
        assert computed == expected, minor


def readme_verdicts():
    """Claim id -> verdict, from the claims table of docs/getting-started.md."""
    text = (ROOT / "docs" / "getting-started.md").read_text(encoding="utf-8")
    rows = re.findall(r"^\| (C\d+) \|.*\| (reproduced|partly|not reproduced) \|$", text, flags=re.M)
    return dict(rows)


def test_wheel_installs_without_a_compiler_and_reproduces_the_paper(wheel, tmp_path):
    """A clean venv, an install that cannot compile, then ``pmsm2dof reproduce`` from outside the checkout."""
    assert not tmp_path.is_relative_to(ROOT)
    venv = tmp_path / "venv"
    run([sys.executable, "-m", "venv", venv], timeout_s=300)  # no system site-packages
    bin_ = venv / "bin"
    no_compiler = clean_env(PATH=str(bin_), CC="false", CXX="false")
    assert [shutil.which(c, path=no_compiler["PATH"]) for c in COMPILERS] == [None] * len(COMPILERS)

    run([bin_ / "python", "-m", "pip", "install", wheel], timeout_s=1200, cwd=tmp_path, env=no_compiler)
    run([bin_ / "python", "-m", "pip", "check"], timeout_s=120, cwd=tmp_path, env=no_compiler)

    # control: in that environment nothing can be compiled (cffi, installed with the wheel, tries)
    control = (
        "from cffi import FFI\nffi = FFI()\nffi.cdef('int probe(void);')\n"
        "ffi.set_source('probe', 'int probe(void) { return 1; }')\nffi.compile(tmpdir='control')"
    )
    refused = subprocess.run(
        [bin_ / "python", "-c", control], cwd=tmp_path, env=no_compiler, capture_output=True, text=True, timeout=120
    )
    assert refused.returncode != 0 and "CompileError" in refused.stderr, refused.stderr[-2000:]
    assert not list((tmp_path / "control").glob("probe*.so"))

    where = (
        "import json, sys, sysconfig, numpy, pmsm2dof, pmsm2dof._core\n"
        "print(json.dumps([sysconfig.get_path('purelib'), sys.path, pmsm2dof.__file__, pmsm2dof._core.__file__, "
        "numpy.__file__]))"
    )
    outside = tmp_path / "elsewhere"
    outside.mkdir()
    site, path, *modules = json.loads(run([bin_ / "python", "-c", where], 120, cwd=outside, env=no_compiler))
    assert Path(site).is_relative_to(venv)
    assert [p for p in path if "-packages" in p] == [site], path  # no system or user site-packages
    assert not [p for p in path if (outside / p).resolve().is_relative_to(ROOT)], path
    for module in modules:
        assert Path(module).is_relative_to(site), module

    run([bin_ / "pmsm2dof", "reproduce", "--out", "report"], timeout_s=1200, cwd=outside, env=no_compiler)
    claims = json.loads((outside / "report" / "claims.json").read_text())["claims"]
    assert len(claims) == 21
    assert {c["id"]: c["verdict"] for c in claims} == readme_verdicts()


def test_sdist_has_the_c_tree_and_builds_the_same_wheel(wheel, tmp_path):
    """The sdist holds csrc/, ffibuild.py and the package; the wheel built from it is the wheel above."""
    sdist = build(copy_checkout(tmp_path / "checkout"), tmp_path / "sdist", "sdist")
    top = f"{PYPROJECT['name']}-{PYPROJECT['version']}"
    with tarfile.open(sdist) as tar:
        members = {m.name.removeprefix(f"{top}/") for m in tar.getmembers() if m.isfile()}
        tar.extractall(tmp_path, filter="data")
    needed = {n for n in checkout_files() if n.startswith(("csrc/", "src/pmsm2dof/"))}
    needed |= {"ffibuild.py", "setup.py", "pyproject.toml", "MANIFEST.in", "README.md", "LICENSE"}
    assert needed <= members, sorted(needed - members)
    assert not [n for n in members if n.endswith((".so", ".o", ".pyc"))]

    rebuilt = build(tmp_path / top, tmp_path / "from-sdist", "wheel")
    assert rebuilt.name == wheel.name
    assert wheel_names(rebuilt) == wheel_names(wheel)
    with zipfile.ZipFile(rebuilt) as a, zipfile.ZipFile(wheel) as b:
        for name in a.namelist():
            if not name.endswith((".so", "/RECORD")):  # the compiled file holds its build paths
                assert a.read(name) == b.read(name), name


#: The row of status.c's table whose range text (empty) the test takes from a header of its own.
OK_ROW = '[P2D_OK] = {"", ""}'
STATUS_INCLUDE = '#include "pmsm2dof/status.h"'
READ_OK_RANGE = (
    "import importlib.util, sys\n"
    "spec = importlib.util.spec_from_file_location('pmsm2dof._core', sys.argv[1])\n"
    "core = importlib.util.module_from_spec(spec)\n"
    "spec.loader.exec_module(core)\n"
    "print(core.ffi.string(core.lib.p2d_status_range(core.lib.P2D_OK)).decode())"
)


def test_a_later_install_from_the_checkout_sees_a_changed_header(tmp_path):
    """``pip install`` twice from one checkout, a header changed in between: the second install has it.

    The installs use the test environment's setuptools and cffi (``--no-build-isolation``, nothing
    to download), build in the checkout as pip does, and must leave no ``build/`` there.

    The change is in a header only (status.c untouched), the case that a reused ``build/`` got
    wrong: setuptools relinks the extension when a source file is newer than it, never for a
    header, and cffi rewrites its generated C file only when the declarations change.
    """
    src = copy_checkout(tmp_path / "checkout")
    before = files_under(src)
    status_c = src / "csrc" / "src" / "status.c"
    text = status_c.read_text()
    assert text.count(OK_ROW) == 1 and STATUS_INCLUDE in text, f"status.c no longer has {OK_ROW} or its include"
    text = text.replace(STATUS_INCLUDE, f'{STATUS_INCLUDE}\n#include "probe.h"', 1)
    status_c.write_text(text.replace(OK_ROW, '[P2D_OK] = {"", P2D_PROBE_TEXT}'))
    probe_h = src / "csrc" / "src" / "probe.h"
    pip = [sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--no-build-isolation", "--target"]
    for stamp in ("first build", "second build"):
        probe_h.write_text(f'#define P2D_PROBE_TEXT "{stamp}"\n')
        target = tmp_path / stamp.replace(" ", "-")
        run([*pip, target, src], timeout_s=900, cwd=tmp_path, env=clean_env())
        (so,) = target.glob("pmsm2dof/_core*.so")
        assert run([sys.executable, "-I", "-c", READ_OK_RANGE, so], timeout_s=120, cwd=tmp_path).strip() == stamp
        assert not (src / "build").exists()
        left = files_under(src) - before - {"csrc/src/probe.h"}
        assert {n for n in left if ".egg-info/" not in n} == set(), sorted(left)
