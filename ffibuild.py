"""cffi build script of the extension ``pmsm2dof._core``.

The extension is compiled from the C sources of this repository: the deployable
controller (``csrc/src``, float32 C99) and the host-only simulation engine
(``csrc/sim``, double). The C declarations given to cffi are read from the public
headers themselves (preprocessor lines removed), so there is one declaration of
each struct and function; ``csrc/sim/*_inline.h`` hold static inline code that the
engine's sources share, and no declarations, so they are left out. The comment beside each field of
the configuration structs (``*_config_t``, ``*_params_t``: meaning, unit, range) is compiled in as
well (``p2d_field_comment``), for the code generator's headers.
"""

import importlib.util
import re
from pathlib import Path

from cffi import FFI

ROOT = Path(__file__).resolve().parent
CSRC = ROOT / "csrc"
SOURCES = sorted((CSRC / "src").glob("*.c")) + sorted((CSRC / "sim").glob("*.c"))


def in_include_order(headers):
    """The headers, each after the public headers it includes: cffi needs every type declared before its use."""
    by_name = {h.name: h for h in headers}
    ordered, seen = [], set()

    def visit(header):
        if header.name not in seen:
            seen.add(header.name)
            for name in re.findall(r'^\s*#\s*include\s*"(?:pmsm2dof/)?([^"]+)"', header.read_text(), flags=re.M):
                if name in by_name:
                    visit(by_name[name])
            ordered.append(header)

    for header in headers:
        visit(header)
    return ordered


HEADERS = in_include_order(sorted((CSRC / "include" / "pmsm2dof").glob("*.h")))
HEADERS += in_include_order(sorted(h for h in (CSRC / "sim").glob("*.h") if not h.name.endswith("_inline.h")))


def cdef_of(header):
    """The declarations of a header, without preprocessor lines and C++ guards."""
    text = header.read_text()
    text = re.sub(r"#ifdef __cplusplus.*?#endif", "", text, flags=re.S)
    return "\n".join(line for line in text.splitlines() if not line.lstrip().startswith("#"))


def load_cheaders():
    """The package's parser of field comments (src/pmsm2dof/core/cheaders.py), loaded alone: the package
    itself needs the extension this script builds."""
    spec = importlib.util.spec_from_file_location("p2d_cheaders", ROOT / "src" / "pmsm2dof" / "core" / "cheaders.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def c_literal(text):
    """A C string literal of ASCII text."""
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


# the comments of the configuration structs, one line each
COMMENTS = load_cheaders().field_comments((h.read_text() for h in HEADERS), r"\w+_(?:config|params)_t")
# p2d_field_comment(2 i) is the name "<struct>.<field>" of entry i, p2d_field_comment(2 i + 1) its comment, then NULL
COMMENT_TABLE = (
    "static const char *const p2d_field_comments[] = {\n"
    + "".join(f"    {c_literal(k)}, {c_literal(v)},\n" for k, v in COMMENTS.items())
    + "    0};\n"
    + "const char *p2d_field_comment(uint32_t i)\n"
    + "{\n    return i < sizeof p2d_field_comments / sizeof p2d_field_comments[0] ? p2d_field_comments[i] : 0;\n}\n"
)

ffibuilder = FFI()
ffibuilder.cdef("\n".join(cdef_of(h) for h in HEADERS) + "\nconst char *p2d_field_comment(uint32_t i);\n")
ffibuilder.set_source(
    "pmsm2dof._core",
    "\n".join(f'#include "{h.relative_to(CSRC / "include") if "include" in h.parts else h.name}"' for h in HEADERS)
    + "\n"
    + COMMENT_TABLE,
    sources=[str(s.relative_to(ROOT)) for s in SOURCES],
    include_dirs=[str(CSRC / "include"), str(CSRC / "sim")],
    # -ffp-contract=off: a*b+c unfused, as on the MCU. -fno-tree-slp-vectorize: the SLP vectorizer
    # packs the plant's state (id, iq, w_m) into register pairs and spends more on shuffling them than
    # it saves (measured with callgrind on the RK4 step of the engine); the results are the same.
    extra_compile_args=["-std=c99", "-O2", "-ffp-contract=off", "-fno-tree-slp-vectorize"],
    libraries=["m"],
)

if __name__ == "__main__":
    ffibuilder.compile(verbose=True)
