"""The command line's spelling: unit suffixes, renamed options, identify's sub-commands, the extras.

docs/conventions.md, "Units": an option of a quantity with a unit ends with the unit suffix of its
scenario key or library argument; a former spelling answers with one line that names the new one.
"""

import re

import click
import pytest

from pmsm2dof.core.bindings import field_comment
from pmsm2dof.ui.cli import cli, main
from pmsm2dof.ui.cli.options import RENAMED, REPLACED

#: The unit suffixes of the scenario keys and library arguments (docs/conventions.md).
UNIT = re.compile(r"_(s|radps|kgm2|H|Wb|A|V|ohm|Hz|deg|dB|rpm|Nm|pct|Nm_per_rad|Nms_per_rad|rpm_per_Nm)$")


def commands(group=cli, path=()):
    """Every command of the CLI as (its words, the command)."""
    for name, command in group.commands.items():
        if isinstance(command, click.Group):
            yield from commands(command, (*path, name))
        else:
            yield (*path, name), command


def options(command):
    return [p for p in command.params if isinstance(p, click.Option)]


def test_every_option_of_a_quantity_with_a_unit_ends_with_its_suffix():
    checked = 0
    for words, command in commands():
        for option in options(command):
            suffix = UNIT.search(option.name)
            if suffix and not option.is_flag:
                checked += 1
                dashed = "-" + suffix.group(1).replace("_", "-")
                assert all(opt.endswith(dashed) for opt in option.opts), (words, option.opts)
    assert checked > 40  # design, bode, twomass, identify, autotune ...


def test_no_command_has_a_former_spelling():
    for words, command in commands():
        names = {opt for option in options(command) for opt in option.opts}
        assert not names & (set(RENAMED) | set(REPLACED)), words


def test_every_former_spelling_answers_with_the_new_one(capsys):
    tried = set()
    for words, command in commands():
        names = {opt for option in options(command) for opt in option.opts}
        for old, new in RENAMED.items():
            if new in names:
                tried.add(old)
                assert main([*words, old, "1"]) == 2
                err = capsys.readouterr().err
                assert (
                    err
                    == f"pmsm2dof: error: {old} is spelled {new} now (an option carries the unit of its scenario key)\n"
                )
                assert main([*words, f"{old}=1"]) == 2
                assert f"is spelled {new} now" in capsys.readouterr().err
    assert tried == set(RENAMED)  # each in every command that has its new spelling


def test_a_replaced_option_names_its_replacement(capsys):
    tried = set()
    for words, command in commands():
        names = {opt for option in options(command) for opt in option.opts}
        for old, (new, why) in REPLACED.items():
            if new in names and words == ("tune",):
                tried.add(old)
                assert main([*words, old, "x"]) == 2
                assert capsys.readouterr().err == f"pmsm2dof: error: {old} is replaced by {new}: {why}\n"
    assert tried == set(REPLACED)


@pytest.mark.parametrize(
    ("argv", "told"),
    [
        (["identify", "log.csv", "--electrical", "--pole-pairs", "4"], "identify electrical log.csv --pole-pairs 4"),
        (["identify", "--plan", "--motor", "d.toml", "--out", "p"], "identify plan --motor d.toml --out p"),
        (["identify", "log.csv", "--motor", "d.toml"], "identify mechanics log.csv --motor d.toml"),
    ],
)
def test_identify_without_a_sub_command_names_the_one_to_use(argv, told, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    captured = capsys.readouterr()
    assert captured.err == f"pmsm2dof: error: identify takes a sub-command: use `pmsm2dof {told}`\n"
    assert captured.out == "" and not any(tmp_path.iterdir())


def test_the_speed_controller_options_read_their_help_from_speed_h():
    """alpha's meaning, unit and range are written once, in the header; three commands show them."""
    text = field_comment("p2d_speed_config_t", "alpha_radps")
    assert "[rad/s]" in text and "eq 9" in text
    helps = {
        words: option.help
        for words, command in commands()
        for option in options(command)
        if option.name == "alpha_radps"
    }
    assert set(helps) == {("design",), ("bode",), ("twomass",)}
    assert all(h == text for h in helps.values())


@pytest.mark.parametrize(
    ("argv", "module", "extra"),
    [
        (["tune", "--no-browser", "--port", "0"], "starlette", "tuner"),
        (["tune", "--no-browser", "--port", "0"], "uvicorn", "tuner"),
        (["sweep", "s.toml", "--out", "o", "--scheduler", "tcp://127.0.0.1:1"], "distributed", "dask"),
        (["autotune", "paper-condition-1", "--scheduler", "tcp://127.0.0.1:1"], "distributed", "dask"),
    ],
)
def test_a_command_without_its_extra_names_it(argv, module, extra, capsys, monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setitem(__import__("sys").modules, module, None)  # as if not installed: find_spec gives None
    assert main(argv) == 2
    captured = capsys.readouterr()
    assert captured.err.count("\n") == 1 and f"python3 -m pip install 'pmsm2dof[{extra}]'" in captured.err
    assert captured.out == "" and not any(tmp_path.iterdir())
