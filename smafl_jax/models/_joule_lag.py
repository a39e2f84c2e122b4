"""The paper's eq. (7) identification model: Joule thermal lag from ``U^2`` plus an output offset.

``y(k) = theta(k) + offset`` with ``theta`` the `JouleThermal` state.  The paper
fits ``T(s)/M'(s) = K2 / (s + K1)`` from the squared drive voltage straight to
the displacement; a measured displacement does not rest at 0 mm, so the offset
(the output at 0 V) is part of the model.  Here ``K1`` is the lag's pole and
``K2 / K1`` its static gain in output units per V^2 -- a different quantity
from the cascade's ``k2``, which the displacement does not determine.
"""

from __future__ import annotations

import dataclasses

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .. import _config  # noqa: F401
from .._io import register_model
from ._constraints import POSITIVE_FLOOR, parameter
from ._thermal import JouleThermal

__all__ = ["JouleLag"]


@register_model
class JouleLag(eqx.Module):
    """First-order lag from ``U^2`` to the output, with an offset (paper's eq. 7).

    For a fixed ``k1`` the output is linear in the static gain ``k2 / k1`` (>= 0) and the offset: the same
    linear-weights protocol as a hysteresis model (`features`, `linear_weights`, `with_linear_weights`,
    `nonnegative_columns`), so `smafl_jax.identify.fit` profiles both out by bounded least squares.
    """

    #: The output is ``features(u, dt) @ linear_weights()`` (a class constant, not a field).
    linear_in_weights = True

    thermal: JouleThermal = eqx.field(default_factory=JouleThermal)
    offset: jnp.ndarray = parameter(default_factory=lambda: jnp.asarray(0.0))

    def simulate(self, u, dt):
        """Output for voltage record ``u`` sampled every ``dt`` seconds."""
        return self.thermal.simulate(u, dt) + self.offset

    def for_record(self, i: int) -> JouleLag:
        """The model as it starts record ``i`` of a joint fit (`JouleThermal.for_record`)."""
        th = self.thermal.for_record(i)
        return self if th is self.thermal else eqx.tree_at(lambda m: m.thermal, self, th)

    def features(self, u, dt):
        """Design matrix ``(T, 2)``: the lag of ``U^2`` with unit static gain (``k2 = k1``) and a column of ones."""
        lag = dataclasses.replace(self.thermal, k2=self.thermal.k1).simulate(u, dt)
        return jnp.stack([lag, jnp.ones_like(lag)], axis=1)

    def linear_weights(self):
        """``[k2 / k1, offset]`` in the column order of `features`."""
        return jnp.stack([self.thermal.k2 / self.thermal.k1, jnp.asarray(self.offset, dtype=jnp.float64)])

    def with_linear_weights(self, theta) -> JouleLag:
        """Copy with static gain ``theta[0]`` (floored at `POSITIVE_FLOOR`: ``k2`` stays positive) and offset ``theta[1]``."""
        g = jnp.maximum(jnp.asarray(theta[0]), POSITIVE_FLOOR)
        return eqx.tree_at(lambda m: (m.thermal.k2, m.offset), self, (g * self.thermal.k1, jnp.asarray(theta[1])))

    def nonnegative_columns(self) -> np.ndarray:
        """The static gain is >= 0, the offset free."""
        return np.array([True, False])

    def describe(self) -> list[str]:
        """The thermal stage's lines, then the offset and the static gain, for a fit report (``report.md``)."""
        th = self.thermal
        gain = float(th.k2) / float(th.k1)
        return [*th.describe(), f"offset = {float(self.offset):.6g}; static gain k2/k1 = {gain:.6g} per V^2"]
