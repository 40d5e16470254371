"""Modules loaded on first use, so that a command that never needs them never pays their import.

python-control (with SciPy under it) takes about a second to import; the analysis modules use it
throughout, but a simulation that only runs their sampled-loop stability check with an ideal
sensor needs numpy alone.

The stand-in :func:`lazy_module` returns imports the module with :func:`importlib.import_module`
on the first attribute read, and reads every attribute from it. It stays out of ``sys.modules``
until then, so that a module nobody used is not there at all. It is not the standard library's
:class:`importlib.util.LazyLoader`: before Python 3.13 a module that loader made is not
thread-safe (CPython issue gh-114763): a thread that reads it while another is executing it sees
it half-made (``module 'control' has no attribute 'tf'``), which a sweep's threads running the
sampled-loop check of a scenario with a sensor chain did. The import system's own per-module lock
makes every other thread wait until the module is whole.
"""

import importlib
import importlib.util
import sys
from types import ModuleType
from typing import Any


class _LazyModule(ModuleType):
    """Stands in for the module of its name until an attribute is read, then reads from it."""

    def __getattr__(self, attr: str) -> Any:
        # called only for what the stand-in does not hold itself: every attribute of the module
        return getattr(importlib.import_module(self.__name__), attr)


def lazy_module(name: str) -> ModuleType:
    """The module ``name``, imported when one of its attributes is first read.

    A module already imported is returned as it is.
    """
    if name in sys.modules:
        return sys.modules[name]
    if importlib.util.find_spec(name) is None:
        raise ModuleNotFoundError(f"No module named {name!r}", name=name)
    return _LazyModule(name)
