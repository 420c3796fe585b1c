"""Stage 1: the rotor FEM (elements, linear parameters, effects, model files)."""

from twin.fem.effects import Effect, effect_classes, register
from twin.fem.elements import Bearing, Disk, Material, ShaftElement, ThrustBearing
from twin.fem.model import RotorModel, Sensor
from twin.fem.modelfile import load_model, shipped_model
from twin.fem.parameters import Parameter, Term
from twin.fem.ross import from_ross, load_ross

__all__ = [
    "Bearing",
    "Disk",
    "Effect",
    "Material",
    "Parameter",
    "RotorModel",
    "Sensor",
    "ShaftElement",
    "Term",
    "ThrustBearing",
    "effect_classes",
    "from_ross",
    "load_model",
    "load_ross",
    "register",
    "shipped_model",
]
