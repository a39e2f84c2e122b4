"""The paper's eq. (7) identification model: Joule thermal lag from ``U^2`` plus an output offset.

``y(k) = theta(k) + offset`` with ``theta`` the `JouleThermal` state.  The paper
fits ``T(s)/M'(s) = K2 / (s + K1)`` from the squared drive voltage straight to
the displacement; a measured displacement does not rest at 0 mm, so the offset
(the output at 0 V) is part of the model.  Here ``K1`` is the lag's pole and
``K2 / K1`` its static gain in output units per V^2 -- a different quantity
from the cascade's ``k2``, which the displacement does not determine.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp

from .. import _config  # noqa: F401
from .._io import register_model
from ._constraints import parameter
from ._thermal import JouleThermal

__all__ = ["JouleLag"]


@register_model
class JouleLag(eqx.Module):
    """First-order lag from ``U^2`` to the output, with an offset (paper's eq. 7)."""

    thermal: JouleThermal = eqx.field(default_factory=JouleThermal)
    offset: jnp.ndarray = parameter(default_factory=lambda: jnp.asarray(0.0))

    def simulate(self, u, dt):
        """Output for voltage record ``u`` sampled every ``dt`` seconds."""
        return self.thermal.simulate(u, dt) + self.offset
