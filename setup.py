"""Build hook: setuptools compiles the cffi extension ``pmsm2dof._core`` (see ffibuild.py).

The build directory is a fresh temporary one on every build, removed at the end: a ``build/``
in the checkout would be reused by a later install, whose compiler does not see a changed
header (setuptools rebuilds an object only when its own .c file is newer).
"""

import atexit
import shutil
import tempfile

from setuptools import setup

BUILD_BASE = tempfile.mkdtemp(prefix="pmsm2dof-build-")
atexit.register(shutil.rmtree, BUILD_BASE, ignore_errors=True)

setup(cffi_modules=["ffibuild.py:ffibuilder"], options={"build": {"build_base": BUILD_BASE}})
