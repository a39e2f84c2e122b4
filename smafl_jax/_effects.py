"""Compatibility module: the effect catalogue lives in `smafl_jax.effects` (issue 12).

`smafl_jax.effects.protocol` (the effect protocol and registry), `smafl_jax.effects.catalogue` (one class per
effect) and `smafl_jax.effects.extended` (`ExtendedModel`, which runs the stages generically).  This module
re-exports their names so that earlier imports keep working; saved models name classes only, not modules.
"""

from __future__ import annotations

from .effects import (
    ACCUMULATION_TIME,
    DRIFT_TIME,
    EFFECT_NAMES,
    EFFECTS,
    RATE_TIME,
    STAGES,
    AbstractEffect,
    AmbientDrift,
    AsymmetricCooling,
    Creep,
    Delay,
    Effect,
    ExtendedModel,
    InputWarp,
    LoadBound,
    LoadDependence,
    NonlinearCooling,
    OutputSaturation,
    RateDependence,
    ResistanceTC,
    SensorLag,
    StrainAccumulation,
    effect_names,
    fractional_delay,
    register_effect,
    warp_input,
)
from .effects.catalogue import _lowpass  # noqa: F401

__all__ = [
    "ACCUMULATION_TIME",
    "DRIFT_TIME",
    "EFFECTS",
    "EFFECT_NAMES",
    "RATE_TIME",
    "STAGES",
    "AbstractEffect",
    "AmbientDrift",
    "AsymmetricCooling",
    "Creep",
    "Delay",
    "Effect",
    "ExtendedModel",
    "InputWarp",
    "LoadBound",
    "LoadDependence",
    "NonlinearCooling",
    "OutputSaturation",
    "RateDependence",
    "ResistanceTC",
    "SensorLag",
    "StrainAccumulation",
    "effect_names",
    "fractional_delay",
    "register_effect",
    "warp_input",
]
