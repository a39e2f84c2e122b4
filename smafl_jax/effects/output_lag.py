"""Catalogue effect `output_lag`: the output sensor responds through a first-order lag (issue 13).

One self-contained class in its own file (a new effect is one class in one file); importing this module registers it
(``smafl_jax.effects`` imports it after the built-in catalogue).  Why a catalogue entry of its own: `sensor_lag` lags the
*input* (the drive or the thermocouple the hysteresis is heard through), `creep` relaxes a bounded *fraction* of the
output over tens of seconds and `delay` shifts the drive without smoothing.  A displacement sensor with a filtered
output (LVDT conditioning, a laser sensor's averaging, a filtered load cell) lags the *whole* measured output:
the independent plant's ``sensor_lag`` (tests/indep_plant.py) and plant B's sensor lag are of this kind.
"""

from __future__ import annotations

from typing import ClassVar

import jax.numpy as jnp
import numpy as np

from .. import _config  # noqa: F401
from ..models._constraints import positive
from .catalogue import _lowpass  # the catalogue's zero-order-hold lag, at rest with the first row
from .protocol import AbstractFeatureEffect, LogBox, Nonlinear, register_effect

__all__ = ["OutputLag"]

_a = jnp.asarray


@register_effect
class OutputLag(AbstractFeatureEffect):
    """First-order lag between the actuator's output and its measurement (a filtered displacement sensor)."""

    name: ClassVar[str] = "output_lag"
    lookalikes: ClassVar[tuple[str, ...]] = ("timing",)
    needs: ClassVar[tuple] = ("time",)
    physics: ClassVar[str] = (
        "The displacement (or force) sensor reports the actuator's output through a first-order lag of time constant "
        "tau: signal conditioning of an LVDT, the averaging of a laser sensor, a filtered load cell. The measured output "
        "is y_m(k) = a y_m(k-1) + (1 - a) y(k), a = exp(-dt/tau), y_m(0) = y(0) (exact for a zero-order-hold output). "
        "Unlike sensor_lag (a lag of the input, heard through the Joule heating and the hysteresis) it smooths the "
        "output's own jumps at reversals; unlike creep (a bounded fraction relaxing over tens of seconds) the whole "
        "output follows; unlike delay it smooths instead of shifting. The lag acts on the design columns, so the gains stay linear."
    )
    parameters: ClassVar[dict] = {
        "tau": "output sensor time constant in seconds (> 0), fitted within [TAU_MIN_SAMPLES dt, TAU_MAX_FRACTION x record]"
    }
    synthetic: ClassVar[str] = "tau ~ U(1, 5) s, at least 3 samples"
    #: Fitting range of ``tau`` (models saved with values outside it still load and run unchanged): from a quarter of a
    #: sample (hardly visible) to a quarter of the training stretch.  Why bounded (as creep is): a lag much longer than
    #: the record flattens every column, and gains scaled up by the inverse of that flattening extrapolate wildly.
    TAU_MIN_SAMPLES: ClassVar[float] = 0.25
    TAU_MAX_FRACTION: ClassVar[float] = 0.25
    tau: jnp.ndarray = positive()

    def filter_features(self, F, dt):
        # at rest with the first row: a constant column stays constant, so the offset and the gains stay linear
        return _lowpass(F, dt, self.tau)

    @classmethod
    def tau_bounds(cls, dt, duration):
        """Fitting range of ``tau`` (s)."""
        lo = cls.TAU_MIN_SAMPLES * float(dt)
        return lo, max(cls.TAU_MAX_FRACTION * float(duration), 16.0 * lo)

    @classmethod
    def nonlinear(cls, ctx):
        return (Nonlinear("tau", LogBox(*cls.tau_bounds(ctx["dt"], ctx["duration"])), 0.5),)

    @classmethod
    def _taus(cls, ctx, samples):
        # kept a factor 2 inside the bounds, where the logistic map of `LogBox` is not flat
        lo, hi = cls.tau_bounds(ctx["dt"], ctx["duration"])
        return list(dict.fromkeys(float(t) for t in np.clip(np.asarray(samples) * ctx["dt"], 2.0 * lo, 0.5 * hi)))

    @classmethod
    def grid(cls, ctx):
        # lags of 1 to 512 samples: sensor filters from a few ms at 100 Hz to a minute at 5 Hz
        return [cls(tau=_a(t)) for t in cls._taus(ctx, 2.0 ** np.arange(10))]

    @classmethod
    def probes(cls, ctx):
        # a weak lag is -tau dy/dt to first order (like a weak output delay); longer lags carry the smoothing signature
        return [cls(tau=_a(t)) for t in cls._taus(ctx, [1.0, 8.0, 32.0])]

    @classmethod
    def synthesise(cls, rng, ctx):
        return cls(tau=_a(max(rng.uniform(1.0, 5.0), 3.0 * float(ctx["dt"])))), {}
