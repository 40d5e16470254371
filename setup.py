"""Build hook: setuptools compiles the cffi extension ``pmsm2dof._core`` (see ffibuild.py).

The build directory is a fresh temporary one on every build, removed at the end: a ``build/``
in the checkout would be reused by a later install, whose compiler does not see a changed
header (setuptools rebuilds an object only when its own .c file is newer).

The wheel is tagged for the stable ABI (``cp311-abi3-<platform>``, one wheel for every CPython
>= 3.11) when cffi compiled the extension for it: cffi defines ``Py_LIMITED_API`` and marks the
extension ``py_limited_api`` except on debug and free-threaded interpreters, whose wheels keep
the interpreter's own ABI tag.
"""

import atexit
import re
import shutil
import tempfile

from setuptools import setup
from setuptools.command.bdist_wheel import bdist_wheel

BUILD_BASE = tempfile.mkdtemp(prefix="pmsm2dof-build-")
atexit.register(shutil.rmtree, BUILD_BASE, ignore_errors=True)


class StableAbiWheel(bdist_wheel):
    """``bdist_wheel`` whose tag is ``abi3`` exactly when the extension was built for the stable ABI."""

    def finalize_options(self):
        if not self.py_limited_api and all(ext.py_limited_api for ext in self.distribution.ext_modules):
            python_requires = str(self.distribution.python_requires)
            oldest = re.fullmatch(r">=\s*3\.(\d+)", python_requires)
            if oldest is None:
                raise ValueError(f"requires-python is {python_requires!r}; the abi3 tag needs the form '>=3.N'")
            self.py_limited_api = f"cp3{oldest[1]}"
        super().finalize_options()


setup(
    cffi_modules=["ffibuild.py:ffibuilder"],
    cmdclass={"bdist_wheel": StableAbiWheel},
    options={"build": {"build_base": BUILD_BASE}},
)
