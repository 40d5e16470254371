"""cffi build script of the extension ``pmsm2dof._core``.

The extension is compiled from the C sources of this repository: the deployable
controller (``csrc/src``, float32 C99) and the host-only simulation engine
(``csrc/sim``, double). The C declarations given to cffi are read from the public
headers themselves (preprocessor lines removed), so there is one declaration of
each struct and function.
"""

import re
from pathlib import Path

from cffi import FFI

ROOT = Path(__file__).resolve().parent
CSRC = ROOT / "csrc"
# status.h first: the other headers use its types
HEADERS = sorted((CSRC / "include" / "pmsm2dof").glob("*.h"), key=lambda h: (h.name != "status.h", h.name))
# drive.h last among the engine's headers: it uses the types of the others
HEADERS += sorted((CSRC / "sim").glob("*.h"), key=lambda h: (h.name == "drive.h", h.name))
SOURCES = sorted((CSRC / "src").glob("*.c")) + sorted((CSRC / "sim").glob("*.c"))


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
