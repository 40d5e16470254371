"""cffi build script of the extension ``pmsm2dof._core``.

The extension is compiled from the C sources of this repository: the deployable
controller (``csrc/src``, float32 C99) and the host-only simulation engine
(``csrc/sim``, double). The C declarations given to cffi are read from the public
headers themselves (preprocessor lines removed), so there is one declaration of
each struct and function; ``csrc/sim/*_inline.h`` hold static inline code that the
engine's sources share, and no declarations, so they are left out.
"""

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


ffibuilder = FFI()
ffibuilder.cdef("\n".join(cdef_of(h) for h in HEADERS))
ffibuilder.set_source(
    "pmsm2dof._core",
    "\n".join(f'#include "{h.relative_to(CSRC / "include") if "include" in h.parts else h.name}"' for h in HEADERS),
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
