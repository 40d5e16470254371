"""The C API page of the documentation (docs/_ext/c_headers.py) shows every public declaration.

The truth is taken outside the page's parser: the struct fields as cffi compiled them into
``pmsm2dof._core``, the function names by a plain text search of the headers. A header with a
function without comment or a float field without a unit must be reported.
"""

import logging
import re
import sys
from pathlib import Path

import pytest

pytest.importorskip("sphinx", reason="the docs extra is not installed: python3 -m pip install -e '.[docs]'")

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "docs" / "_ext"))
import c_headers  # noqa: E402

from pmsm2dof.core.bindings import ffi  # noqa: E402

HEADERS = c_headers.public_headers()


def page_of(paths):
    """The reST of the C API page for ``paths``, given in an order where each follows the types it uses."""
    ast = c_headers.parse_headers(paths)
    return "\n".join("\n".join(c_headers.rst_of(c_headers.Header(p, ast))) for p in sorted(paths))


def test_every_public_function_is_on_the_page_with_its_comment():
    page = page_of(HEADERS)
    assert sorted(HEADERS) == sorted((ROOT / "csrc" / "include" / "pmsm2dof").glob("*.h"))
    names = set()
    for header in HEADERS:
        code = re.sub(r"/\*.*?\*/", "", header.read_text(), flags=re.S)
        names |= set(re.findall(r"\b(p2d_\w+)\s*\(", code))
    assert len(names) >= 20
    for name in names:
        block = re.search(rf"^\.\. c:function:: .*\b{name}\(.*\n\n((?:   .*\n|\n)+?)(?=\S|\Z)", page + "\n", re.M)
        assert block, name
        assert block.group(1).strip(), f"{name}: no comment"


def test_every_field_of_every_public_struct_is_on_the_page_with_its_comment_and_unit():
    page = page_of(HEADERS)
    text = "".join(h.read_text() for h in HEADERS)
    structs = [name for name in ffi.list_types()[0] if re.search(rf"\}}\s*{name}\s*;", text) and name.endswith("_t")]
    structs = [name for name in structs if ffi.typeof(name).kind == "struct"]
    assert {"p2d_speed_config_t", "p2d_speed_t", "p2d_current_config_t", "p2d_pi_coef_t"} <= set(structs)
    for struct in structs:
        section = page.split(f".. c:struct:: {struct}\n", 1)[1].split("\n.. c:", 1)[0]
        for field, ctype in ffi.typeof(struct).fields:
            found = re.search(rf"^   \.\. c:member:: .*\b{field}(\[\d+\])?\n\n      (.+)$", section, re.M)
            assert found, f"{struct}.{field}"
            if ctype.type.cname == "float":
                unit = re.search(r"(?<![\w\]])\[[^\]]+\]", found.group(2).replace("\\", ""))
                assert unit, f"{struct}.{field}: no unit in {found.group(2)!r}"


def test_a_function_without_comment_and_a_float_without_unit_are_reported(tmp_path, caplog):
    header = tmp_path / "demo.h"
    header.write_text(
        "/*\n * demo: a header of the test.\n */\n"
        "typedef struct {\n"
        "    float x_Nm; /* torque [Nm] */\n"
        "    float y;    /* a number without its unit, y[k-1] */\n"
        "} demo_t;\n\n"
        "/* Step the demo. */\n"
        "void demo_step(demo_t *d);\n"
        "void demo_reset(demo_t *d);\n"
    )
    with caplog.at_level(logging.WARNING):
        page_of([header])
    warnings = [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]
    assert warnings == ["field demo_t.y: no [unit] in its comment", "function demo_reset has no comment above it"]
