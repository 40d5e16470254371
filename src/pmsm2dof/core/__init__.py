"""The controller: bindings to the C library and the Python objects over its controllers.

The lowest layer of pmsm2dof (above :mod:`pmsm2dof.errors` and :mod:`pmsm2dof.outputs`): it
imports nothing of the other layers. :mod:`.bindings` holds the compiled library and the names
read from its headers, :mod:`.controllers` the :class:`SpeedController` and
:class:`CurrentController` that wrap the deployable C controllers, :mod:`.sensing` the
:class:`Encoder` speed estimators and the :class:`FieldWeakening`, :mod:`.fixedpoint` the
:class:`FixedPointSpeedController` (Q15, Q31) for MCUs without an FPU, :mod:`.gains` eq 9,
:mod:`.fields` the generic setter of the C structs' fields, :mod:`.motor` the one :class:`~.motor.Motor`
type and its loader (datasheet units, scenarios, identified motor files).
"""

from .bindings import (
    ANTI_WINDUPS,
    ARITHMETICS,
    CURRENT_LOOP_MODELS,
    ESTIMATORS,
    FAULT_KINDS,
    FEEDBACKS,
    FEEDFORWARDS,
    LOG_COLUMNS,
    LOG_RATES,
    MECHANICS_MODELS,
    METHODS,
    SPEED_SENSOR_MODELS,
)
from .controllers import CurrentController, CurrentOutput, SpeedController, SpeedOutput
from .fixedpoint import FixedPointOutput, FixedPointSpeedController
from .gains import pi_gains
from .sensing import Encoder, EncoderOutput, FieldWeakening, FieldWeakeningOutput

__all__ = [
    "ANTI_WINDUPS",
    "ARITHMETICS",
    "CURRENT_LOOP_MODELS",
    "ESTIMATORS",
    "FAULT_KINDS",
    "FEEDBACKS",
    "FEEDFORWARDS",
    "LOG_COLUMNS",
    "LOG_RATES",
    "MECHANICS_MODELS",
    "METHODS",
    "SPEED_SENSOR_MODELS",
    "CurrentController",
    "CurrentOutput",
    "Encoder",
    "EncoderOutput",
    "FieldWeakening",
    "FieldWeakeningOutput",
    "FixedPointOutput",
    "FixedPointSpeedController",
    "SpeedController",
    "SpeedOutput",
    "pi_gains",
]
