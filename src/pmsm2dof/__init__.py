"""pmsm2dof: anti-windup and 2DOF PI speed control of a PMSM, from design to the MCU.

Implements Wang, Lin, Yang, Fang, "Anti-Windup and 2DOF Design for Permanent-Magnet
Synchronous Motor Speed Controller" (equation numbers in docstrings are the paper's).

The package is layered, imports pointing down only: :mod:`pmsm2dof.ui` (command line, plots,
report, tuner) over :mod:`pmsm2dof.studies` (many runs) over :mod:`pmsm2dof.sim` (scenarios,
the simulation engine, metrics) and :mod:`pmsm2dof.analysis` (design, discretization, margins,
C headers) over :mod:`pmsm2dof.core` (the C controllers), all over :mod:`pmsm2dof.errors` and
:mod:`pmsm2dof.outputs`. The names below are loaded on first use, so that ``import pmsm2dof``
costs nothing until one is used.
"""

import importlib
from typing import TYPE_CHECKING, Any

#: Public name -> module that defines it.
_EXPORTS = {
    "ConfigError": "pmsm2dof.errors",
    "Pmsm2dofError": "pmsm2dof.errors",
    "SimulationError": "pmsm2dof.errors",
    "ANTI_WINDUPS": "pmsm2dof.core",
    "FEEDFORWARDS": "pmsm2dof.core",
    "METHODS": "pmsm2dof.core",
    "CurrentController": "pmsm2dof.core",
    "SpeedController": "pmsm2dof.core",
    "Encoder": "pmsm2dof.core",
    "FieldWeakening": "pmsm2dof.core",
    "SensorChain": "pmsm2dof.analysis.sensor",
    "Design": "pmsm2dof.analysis.design",
    "design": "pmsm2dof.analysis.design",
    "DiscreteDesign": "pmsm2dof.analysis.discretize",
    "SamplingWarning": "pmsm2dof.analysis.discretize",
    "Scenario": "pmsm2dof.sim.scenario",
    "list_presets": "pmsm2dof.sim.scenario",
    "load_scenario": "pmsm2dof.sim.scenario",
    "compute_metrics": "pmsm2dof.sim.metrics",
    "Result": "pmsm2dof.sim.simulate",
    "simulate": "pmsm2dof.sim.simulate",
    "simulate_many": "pmsm2dof.sim.simulate",
    "AutotuneResult": "pmsm2dof.studies.autotune",
    "Spec": "pmsm2dof.studies.autotune",
    "autotune": "pmsm2dof.studies.autotune_search",
}

__all__ = [
    "ANTI_WINDUPS",
    "FEEDFORWARDS",
    "METHODS",
    "AutotuneResult",
    "ConfigError",
    "CurrentController",
    "Design",
    "DiscreteDesign",
    "Encoder",
    "FieldWeakening",
    "Pmsm2dofError",
    "Result",
    "SamplingWarning",
    "Scenario",
    "SensorChain",
    "SimulationError",
    "Spec",
    "SpeedController",
    "autotune",
    "compute_metrics",
    "design",
    "list_presets",
    "load_scenario",
    "simulate",
    "simulate_many",
]

if TYPE_CHECKING:
    from .analysis.design import Design, design
    from .analysis.discretize import DiscreteDesign, SamplingWarning
    from .analysis.sensor import SensorChain
    from .core import ANTI_WINDUPS, FEEDFORWARDS, METHODS, CurrentController, Encoder, FieldWeakening, SpeedController
    from .errors import ConfigError, Pmsm2dofError, SimulationError
    from .sim.metrics import compute_metrics
    from .sim.scenario import Scenario, list_presets, load_scenario
    from .sim.simulate import Result, simulate, simulate_many
    from .studies.autotune import AutotuneResult, Spec
    from .studies.autotune_search import autotune


def __getattr__(name: str) -> Any:
    """Load a public name from its module on first use (PEP 562)."""
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'pmsm2dof' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
