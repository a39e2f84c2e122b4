"""Cascade actuator model: voltage -> Joule heat -> thermal state -> hysteresis (EUPI by default) -> displacement.

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
import jax.numpy as jnp

from .. import _config  # noqa: F401
from .._errors import UserInputError
from .._io import register_model
from ._eupi import EUPI
from ._hysteresis import AbstractHysteresis
from ._thermal import JouleThermal, _safe_sqrt

__all__ = ["SEES", "Cascade"]

SEES = ("voltage", "heat")
#: ``sees`` of a cascade in its compile form (`Cascade.compile_form`): the choice is the leaf ``heat_input``.
COMPILE_SEES = "data"


@register_model
class Cascade(eqx.Module):
    """Thermal model followed by a hysteresis model (`AbstractHysteresis`: EUPI, Preisach)."""

    #: The output is ``features(u, dt) @ hysteresis.linear_weights()`` (a class constant, not a field).
    linear_in_weights = True
    #: May be the base of an `ExtendedModel` (see `AbstractHysteresis.extendable`).
    extendable = True

    thermal: JouleThermal
    hysteresis: AbstractHysteresis
    # What the hysteresis acts on: "voltage" = the effective voltage sqrt(theta k1/k2) (the paper's
    # voltage-domain EUPI); "heat" = theta k1/k2 = u_eff^2 (V^2), i.e. the temperature rise, where the
    # phase transformation of an SMA really happens. Play operators are not invariant under the square,
    # so the two are different model classes; `smafl fit` screens both.
    sees: str = eqx.field(static=True, default="voltage")
    # A joint fit of several records: the operator-memory rule each record starts by (`AbstractHysteresis.RULE_INITS`;
    # a warm record's operators came up from cold, a cold one's are at rest), with its own thermal start
    # (`JouleThermal.with_record_starts`).  None: the hysteresis' own rule for every record.
    record_inits: tuple[str, ...] | None = eqx.field(static=True, default=None)
    # Only in `compile_form` (sees = "data"): what the hysteresis sees as data, 1.0 heat or 0.0 voltage, so that the
    # screening's voltage and heat candidates share their compiled programs; None in every model a user holds.
    heat_input: jnp.ndarray | None = eqx.field(default=None, metadata={"transient": True})

    def __check_init__(self):
        if self.sees not in SEES and not (self.sees == COMPILE_SEES and self.heat_input is not None):
            raise ValueError(f"Cascade sees must be one of {SEES}, got {self.sees!r}")
        if self.heat_input is not None and self.sees != COMPILE_SEES:
            raise ValueError(f"Cascade heat_input belongs to its compile form (sees={COMPILE_SEES!r}), got sees={self.sees!r}")
        if self.record_inits is not None:
            n = self.thermal.n_record_starts
            if n is None or len(self.record_inits) != n:
                raise ValueError(f"Cascade record_inits needs one rule per record start ({n}), got {self.record_inits!r}")
            bad = [r for r in self.record_inits if r not in self.hysteresis.RULE_INITS]
            if bad:
                raise ValueError(f"Cascade record_inits must be rules of {self.hysteresis.RULE_INITS}, got {bad}")

    def _seen(self, u_eff):
        """What the hysteresis sees of an effective voltage: ``u_eff`` itself or its square (the heat)."""
        if self.sees == COMPILE_SEES:
            return jnp.where(self.heat_input > 0.5, u_eff * u_eff, u_eff)
        return u_eff if self.sees == "voltage" else u_eff * u_eff

    def drive_of(self, theta):
        """Signal the hysteresis sees for thermal state ``theta``."""
        return self._seen(self.thermal.effective_voltage(theta))

    def drive_of_heat(self, q):
        """Signal the hysteresis sees for the thermal state in V^2 units ``q = theta k1 / k2`` (`ExtendedModel`'s state):
        ``sqrt(q)`` (``sees="voltage"``) or ``q`` itself (``sees="heat"``)."""
        if self.sees == COMPILE_SEES:
            return jnp.where(self.heat_input > 0.5, q, _safe_sqrt(q))
        return q if self.sees == "heat" else _safe_sqrt(q)

    def hysteresis_input(self, u, dt):
        return self.drive_of(self.thermal.simulate(u, dt))

    def hysteresis_start(self, u, dt=None):
        """What the hysteresis sees before the first sample of ``u``: the thermal start rule's state (a cold or rest
        start the fit saw, which a trained range must hold)."""
        del dt
        return self.drive_of(self.thermal.initial_state(jnp.asarray(u, dtype=jnp.float64)[0]))

    def steady_drive(self, u):
        """Hysteresis input once a constant voltage ``u`` has been held (``u``, or ``u^2`` for ``sees="heat"``)."""
        return self._seen(u)

    def compile_form(self) -> Cascade:
        """The same cascade with what its hysteresis sees as data (``heat_input``) instead of a static choice (and its
        hysteresis in its own compile form, `AbstractHysteresis.compile_form`: the orientation as data).

        Why: a static field is part of the tree structure that `jax.jit` keys its programs on, so the screening's
        voltage and heat candidates compiled every design, simulation and LM solve twice (session 52: 13 s of the 34 s
        compiling in `smafl fit --model cascade` on a 30 000-sample record).  The jitted entry points of the fit take
        this form (`smafl_jax.models.compile_form`); `user_form` turns a fitted one back."""
        if self.sees == COMPILE_SEES:
            return self
        return dataclasses.replace(
            self,
            hysteresis=self.hysteresis.compile_form(),
            sees=COMPILE_SEES,
            heat_input=jnp.asarray(1.0 if self.sees == "heat" else 0.0),
        )

    def user_form(self) -> Cascade:
        """Inverse of `compile_form` (needs a concrete ``heat_input``)."""
        if self.sees != COMPILE_SEES:
            return self
        return dataclasses.replace(
            self,
            hysteresis=self.hysteresis.user_form(),
            sees="heat" if float(self.heat_input) > 0.5 else "voltage",
            heat_input=None,
        )

    def features(self, u, dt):
        """Design matrix of the hysteresis weights: ``simulate(u, dt) = features(u, dt) @ hysteresis.linear_weights()``."""
        return self.hysteresis.features(self.hysteresis_input(u, dt))

    def with_hysteresis(self, h: AbstractHysteresis) -> Cascade:
        """Copy with the hysteresis part replaced."""
        return eqx.tree_at(lambda m: m.hysteresis, self, h)

    def with_sees(self, sees: str, u_max: float) -> Cascade:
        """Copy whose hysteresis acts on ``sees`` for drives up to ``u_max`` V (same operator grid, range rescaled);
        the start screening (`smafl_jax.identify.screen_start`) tries both inputs."""
        if sees == self.sees:
            return self
        if self.sees == COMPILE_SEES:
            raise ValueError("with_sees needs the cascade's user form (Cascade.user_form)")
        fresh = self.hysteresis.with_range(0.0, u_max if sees == "voltage" else u_max * u_max)
        return dataclasses.replace(self, hysteresis=fresh, sees=sees)

    def for_record(self, i: int) -> Cascade:
        """The model as it starts record ``i`` of a joint fit: its thermal start (`JouleThermal.for_record`) and its
        operator-memory rule (``record_inits``)."""
        th = self.thermal.for_record(i)
        if th is self.thermal:
            return self
        one = eqx.tree_at(lambda m: m.thermal, self, th)  # a leaf swap: works on traced models (the LM's residuals)
        if self.record_inits is None:
            return one
        return dataclasses.replace(one, hysteresis=self.hysteresis.with_init(self.record_inits[i]), record_inits=None)

    def with_record_starts(self, u0s, inits=None) -> Cascade:
        """Copy that starts record ``i`` of a joint fit at the thermal state a constant ``u0s[i]`` V would hold, with the
        operator-memory rule ``inits[i]`` (None: the hysteresis' own rule for all)."""
        th = self.thermal.with_record_starts(u0s)
        return dataclasses.replace(self, thermal=th, record_inits=None if inits is None else tuple(inits))

    def with_thermal_start(self, init: str, u0: float | None = None) -> Cascade:
        """Copy whose thermal stage starts by rule ``init`` (``"given"``: the state a constant ``u0`` V would hold), the
        same for every record."""
        u0 = None if u0 is None else jnp.asarray(float(u0))
        th = dataclasses.replace(self.thermal, init=init, u0=u0)
        return dataclasses.replace(self, thermal=th, record_inits=None)

    def plant_parts(self) -> tuple[JouleThermal, AbstractHysteresis]:
        """``(thermal, hysteresis)``: the per-sample stages `smafl_jax.control.plant_step` runs (ZOH thermal step, then
        the hysteresis step on `drive_of`)."""
        if self.thermal.lag:
            raise UserInputError(
                "closed-loop simulation of a cascade whose drive heats from the next sample (thermal lag=1, chosen by "
                "smafl diagnose for this record's sampling convention) is not supported; refit with lag 0 for control"
            )
        return self.thermal, self.hysteresis

    def describe(self) -> list[str]:
        """The thermal stage's lines, then the hysteresis' (`AbstractHysteresis.describe`), for a fit report."""
        return [*self.thermal.describe(), *self.hysteresis.describe()]

    def states(self, u, dt):
        """Dict of internal signals: ``theta`` (thermal state), ``u_eff``, ``drive`` (hysteresis input), ``y``."""
        theta = self.thermal.simulate(u, dt)
        drive = self.drive_of(theta)
        return {
            "theta": theta,
            "u_eff": self.thermal.effective_voltage(theta),
            "drive": drive,
            "y": self.hysteresis.simulate(drive),
        }

    def simulate(self, u, dt):
        """Displacement for voltage record ``u`` sampled every ``dt`` seconds."""
        return self.hysteresis.simulate(self.hysteresis_input(u, dt))

    def with_method(self, method: str) -> Cascade:
        """Copy with both parts evaluated by ``method`` ("auto", "scan", "assoc", "chunked", "segmented")."""
        return dataclasses.replace(
            self,
            thermal=dataclasses.replace(self.thermal, method=method),
            hysteresis=self.hysteresis.with_method(method),
        )

    @classmethod
    def from_range(cls, u_max, *, thermal=None, sees="voltage", **eupi_kwargs):
        """Untrained cascade for drive voltages in ``[0, u_max]`` (paper defaults for the thermal part)."""
        if sees not in SEES:
            raise ValueError(f"sees must be one of {SEES}, got {sees!r}")
        top = u_max if sees == "voltage" else u_max * u_max
        return cls(
            thermal=thermal if thermal is not None else JouleThermal(),
            hysteresis=EUPI.from_range(0.0, top, **eupi_kwargs),
            sees=sees,
        )
