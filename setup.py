"""Build hook: setuptools compiles the cffi extension ``pmsm2dof._core`` (see ffibuild.py)."""

from setuptools import setup

setup(cffi_modules=["ffibuild.py:ffibuilder"])
