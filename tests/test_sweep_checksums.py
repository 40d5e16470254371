"""A sweep's resumable state is checked before it is used: parts by the SHA-256 in their name,
sweep.json by its own checksum.

Every single-byte change of a part, at every byte of the file, is detected: the part is reported by
name and deleted, never read (before, 125 of 576 flips were read back as wrong values, a point's
J_kgm2 became 6.97e206, and two crashed the resume). A damaged sweep.json is refused saying what is
wrong with it, in one line; --force starts the sweep again and keeps the user's files.
"""

import json
import shutil
import warnings

import pytest

from pmsm2dof.errors import ConfigError
from pmsm2dof.studies.engine import PartStore, PartWarning
from pmsm2dof.studies.sweep import parse_sweep
from pmsm2dof.studies.sweep_run import _parts, run_sweep
from pmsm2dof.ui.cli import main

SWEEP = {"base": "paper-experiment-1", "worst": 0, "axes": {"motor.J_kgm2": [0.3, 0.5]}}


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    """A finished two-point sweep, one point per part: (sweep, folder, name and bytes of a part)."""
    sweep = parse_sweep(json.loads(json.dumps(SWEEP)))
    out = tmp_path_factory.mktemp("sweep") / "out"
    run_sweep(sweep, out, workers=1, batch_size=1, progress=False)
    part = sorted((out / "parts").glob("part-*.parquet"))[0]
    return sweep, out, part.name, part.read_bytes()


def test_every_single_byte_change_of_a_part_is_detected_and_never_read(finished, tmp_path):
    sweep, _out, name, data = finished
    store = PartStore(tmp_path, _parts(tmp_path, sweep).frame, "point", len(sweep.points))
    path = tmp_path / name
    path.write_bytes(data)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sound = store.read()
    assert list(sound["point"]) == [0]
    missed = []
    for i in range(len(data)):
        for flip in (0xFF, 1 << (i % 8)):  # every bit of the byte, and one bit varying with the place
            damaged = bytearray(data)
            damaged[i] ^= flip
            path.write_bytes(damaged)
            with pytest.warns(PartWarning) as caught:
                rows = store.read()
            if rows is not None or path.exists() or len(caught) != 1:
                missed.append((i, flip))
            elif not str(caught[0].message).startswith(f"{tmp_path.name}/{name} of the earlier run"):
                missed.append((i, flip))
    assert missed == [], f"{len(missed)} of {2 * len(data)} changes not detected, e.g. {missed[:5]}"
    assert "does not match its checksum" in str(caught[0].message)


def test_a_part_without_its_checksum_is_recomputed(finished, tmp_path):
    sweep, _out, name, data = finished
    (tmp_path / "part-00000000.parquet").write_bytes(data)  # as an earlier version named it
    store = PartStore(tmp_path, _parts(tmp_path, sweep).frame, "point", len(sweep.points))
    with pytest.warns(PartWarning, match="no checksum in its name"):
        assert store.read() is None


def damaged_manifests(text):
    data = json.loads(text)
    other = dict(data, digest="0" * 64)
    yield "truncated", text[: len(text) // 2], "not valid JSON|valid JSON"
    yield "not an object", "[1, 2]", "not a JSON object with a checksum"
    yield "digest changed", json.dumps(other), "does not match its checksum"
    yield "no checksum", json.dumps({k: v for k, v in data.items() if k != "checksum"}), "with a checksum"
    yield "nested", "[" * 100_000, "nested at most"
    yield "not UTF-8", "\udcff", "UTF-8"


@pytest.mark.parametrize("case", [c for c, _, _ in damaged_manifests('{"a": 1}')])
def test_a_damaged_sweep_json_says_what_is_wrong_in_one_line(finished, tmp_path, capsys, case):
    sweep, out, _name, _data = finished
    original = (out / "sweep.json").read_text()
    ((_c, text, words),) = [m for m in damaged_manifests(original) if m[0] == case]
    folder = tmp_path / "out"
    shutil.copytree(out, folder)  # with the times of the files, which the outputs' manifest holds
    (folder / "sweep.json").write_bytes(text.encode("utf-8", "surrogateescape"))
    with pytest.raises(ConfigError, match=words):
        run_sweep(sweep, folder, workers=1, progress=False)
    (tmp_path / "sweep.toml").write_text(
        'base = "paper-experiment-1"\nworst = 0\n[axes]\n"motor.J_kgm2" = [0.3, 0.5]\n'
    )
    argv = ["sweep", str(tmp_path / "sweep.toml"), "--out", str(folder), "--no-figures"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "sweep.json" in err and "--force" in err and "Traceback" not in err
    (folder / "notes.txt").write_text("mine")
    assert main([*argv, "--force"]) == 0
    assert "(2 simulated, 0 already done)" in capsys.readouterr().out
    assert (folder / "notes.txt").read_text() == "mine"
    assert json.loads((folder / "sweep.json").read_text())["digest"] == sweep.digest()
