"""Cascade actuator model: voltage -> Joule heat -> thermal state -> EUPI -> displacement.

Documented choice of what the hysteresis sees (PAPER.md): the EUPI acts on the
*effective quasi-static voltage* ``u_eff = sqrt(theta k1 / k2)``, the constant
voltage that would hold the thermal state where it is.  At steady state
``u_eff`` equals the applied voltage, so in quasi-static conditions the cascade
is exactly the voltage-domain EUPI identified in the paper (tested), while
fast drives are low-pass filtered by the thermal lag.

Identifiability: ``theta`` scales with ``k2`` and ``u_eff`` divides it out, so
the cascade's displacement depends on the thermal time constant ``1/k1`` but
not on ``k2``.  ``k2`` only has meaning for the Joule model fitted alone
(``U^2`` -> output, the paper's eq. 7) or for a measured temperature.
"""

from __future__ import annotations

import dataclasses

import equinox as eqx

from . import _config  # noqa: F401
from ._eupi import EUPI
from ._io import register_model
from ._thermal import JouleThermal

__all__ = ["Cascade"]


@register_model
class Cascade(eqx.Module):
    """Thermal model followed by EUPI hysteresis."""

    thermal: JouleThermal
    hysteresis: EUPI

    def states(self, u, dt):
        """Dict of internal signals: ``theta`` (thermal state), ``u_eff``, ``y`` (output)."""
        theta = self.thermal.simulate(u, dt)
        u_eff = self.thermal.effective_voltage(theta)
        return {"theta": theta, "u_eff": u_eff, "y": self.hysteresis.simulate(u_eff)}

    def simulate(self, u, dt):
        """Displacement for voltage record ``u`` sampled every ``dt`` seconds."""
        theta = self.thermal.simulate(u, dt)
        return self.hysteresis.simulate(self.thermal.effective_voltage(theta))

    def with_method(self, method: str) -> Cascade:
        """Copy with both parts evaluated by ``method`` ("auto", "scan", "assoc", "chunked", "segmented")."""
        return Cascade(
            thermal=dataclasses.replace(self.thermal, method=method),
            hysteresis=dataclasses.replace(self.hysteresis, method=method),
        )

    @classmethod
    def from_range(cls, u_max, *, thermal=None, **eupi_kwargs):
        """Untrained cascade for drive voltages in ``[0, u_max]`` (paper defaults for the thermal part)."""
        return cls(
            thermal=thermal if thermal is not None else JouleThermal(), hysteresis=EUPI.from_range(0.0, u_max, **eupi_kwargs)
        )
