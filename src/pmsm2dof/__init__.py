"""pmsm2dof: anti-windup and 2DOF PI speed control of a PMSM, from design to the MCU.

Implements Wang, Lin, Yang, Fang, "Anti-Windup and 2DOF Design for Permanent-Magnet
Synchronous Motor Speed Controller" (equation numbers in docstrings are the paper's).
"""

from .controllers import ANTI_WINDUPS, FEEDFORWARDS, METHODS, CurrentController, SpeedController
from .errors import ConfigError, Pmsm2dofError, SimulationError

__all__ = ["ConfigError", "Pmsm2dofError", "SimulationError"]
__all__ += ["ANTI_WINDUPS", "FEEDFORWARDS", "METHODS", "CurrentController", "SpeedController"]
from .design import Design, design
from .discretize import DiscreteDesign, SamplingWarning

__all__ += ["Design", "DiscreteDesign", "SamplingWarning", "design"]
from .metrics import compute_metrics
from .scenario import Scenario, list_presets, load_scenario

__all__ += ["Scenario", "compute_metrics", "list_presets", "load_scenario"]
from .simulate import Result, simulate

__all__ += ["Result", "simulate"]
