"""What the drive link reads from a firmware's ELF file: a file that is no ELF is refused by name."""

import pytest

from pmsm2dof.drive.elf import read_variables
from pmsm2dof.errors import ConfigError


@pytest.mark.parametrize(
    ("content", "valid"), [(b"not an ELF\n", "an ELF file of the firmware"), (None, "a readable ELF file")]
)
def test_a_file_that_is_no_elf_is_refused_naming_it(tmp_path, content, valid):
    path = tmp_path / "firmware.elf"
    if content is not None:
        path.write_bytes(content)
    with pytest.raises(ConfigError) as info:
        read_variables(path, ["p2d_link"])
    assert info.value.param == "elf" and info.value.value == str(path) and info.value.valid.startswith(valid)
