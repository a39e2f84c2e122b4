"""Compatibility module: the effect catalogue lives in `smafl_jax.effects` (issue 12).

`smafl_jax.effects.protocol` (the effect protocol and registry), `smafl_jax.effects.catalogue` (one class per
effect) and `smafl_jax.effects.extended` (`ExtendedModel`, which runs the stages generically).  This module
re-exports their names so that earlier imports keep working; saved models name classes only, not modules.
"""

from __future__ import annotations

from .effects import *  # noqa: F403
from .effects import __all__  # noqa: F401
from .effects.catalogue import _lowpass  # noqa: F401
