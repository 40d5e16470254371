"""Modules loaded on first use, so that a command that never needs them never pays their import.

python-control (with SciPy under it) takes about a second to import; the analysis modules use it
throughout, but a simulation that only runs their sampled-loop stability check with an ideal
sensor needs numpy alone. The loader is the standard library's
:class:`importlib.util.LazyLoader`, used as its documentation describes.
"""

import importlib.util
import sys
from types import ModuleType


def lazy_module(name: str) -> ModuleType:
    """The module ``name``, executed when one of its attributes is first read.

    A module already imported is returned as it is.
    """
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.find_spec(name)
    if spec is None or spec.loader is None:
        raise ModuleNotFoundError(f"No module named {name!r}", name=name)
    loader = importlib.util.LazyLoader(spec.loader)
    spec.loader = loader
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    loader.exec_module(module)
    return module
