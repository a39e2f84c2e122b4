"""Effects that extend the base cascade: the protocol, the catalogue and `ExtendedModel` (issues 6 and 12).

A new effect is one class (a subclass of a stage class of `protocol`, decorated with `register_effect`);
`ExtendedModel` and the diagnosis then use it without further changes.
"""

from __future__ import annotations

import importlib as _importlib
import pkgutil as _pkgutil

from . import catalogue as _catalogue  # noqa: F401  (registers the catalogue, in order)
from .catalogue import (
    ACCUMULATION_TIME,
    DRIFT_TIME,
    RATE_TIME,
    AmbientDrift,
    AsymmetricCooling,
    Creep,
    Delay,
    InputWarp,
    LoadDependence,
    NonlinearCooling,
    OutputSaturation,
    RateDependence,
    ResistanceTC,
    SensorLag,
    StrainAccumulation,
    fractional_delay,
    warp_input,
)
from .extended import ExtendedModel, LoadBound
from .protocol import (
    EFFECTS,
    STAGES,
    AbstractEffect,
    AbstractFeatureEffect,
    AbstractInputEffect,
    AbstractLinearEffect,
    AbstractOutputEffect,
    AbstractThermalEffect,
    AbstractThresholdEffect,
    AbstractWarpEffect,
    Effect,
    Linear,
    Log,
    LogBox,
    Nonlinear,
    OutputLink,
    Tanh,
    Transform,
    effect_rank,
    register_effect,
)

# Every other module of this package is an effect in a file of its own: importing it registers it (after the catalogue,
# in file-name order), so a new effect is one file and nothing else.
_CORE_MODULES = ("protocol", "extended", "catalogue")
for _info in sorted(_pkgutil.iter_modules(__path__), key=lambda m: m.name):
    if _info.name not in _CORE_MODULES:
        _importlib.import_module(f"{__name__}.{_info.name}")

from .output_lag import OutputLag  # noqa: E402  (public: smafl_jax.effects.OutputLag; registered by the loop above)
from .sensor_lead import SensorLead  # noqa: E402  (public: smafl_jax.effects.SensorLead; registered by the loop above)

#: The built-in catalogue names in catalogue order (`effect_names` also lists effects registered later).
EFFECT_NAMES = tuple(EFFECTS)


def effect_names() -> tuple[str, ...]:
    """Registered catalogue names in catalogue order."""
    return tuple(EFFECTS)


def effect_classes() -> list[type]:
    """Every registered effect class (tests parametrise over this list)."""
    return list(EFFECTS.values())


__all__ = [
    "ACCUMULATION_TIME",
    "DRIFT_TIME",
    "EFFECTS",
    "EFFECT_NAMES",
    "RATE_TIME",
    "STAGES",
    "AbstractEffect",
    "AbstractFeatureEffect",
    "AbstractInputEffect",
    "AbstractLinearEffect",
    "AbstractOutputEffect",
    "AbstractThermalEffect",
    "AbstractThresholdEffect",
    "AbstractWarpEffect",
    "AmbientDrift",
    "AsymmetricCooling",
    "Creep",
    "Delay",
    "Effect",
    "ExtendedModel",
    "InputWarp",
    "Linear",
    "LoadBound",
    "LoadDependence",
    "Log",
    "LogBox",
    "Nonlinear",
    "NonlinearCooling",
    "OutputLag",
    "OutputLink",
    "OutputSaturation",
    "RateDependence",
    "ResistanceTC",
    "SensorLag",
    "SensorLead",
    "StrainAccumulation",
    "Tanh",
    "Transform",
    "effect_classes",
    "effect_names",
    "effect_rank",
    "fractional_delay",
    "register_effect",
    "warp_input",
]
