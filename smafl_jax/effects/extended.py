"""`ExtendedModel`: a base model composed with catalogue effects, run stage by stage (issue 6, issue 12).

`ExtendedModel(base, effects)` composes a base model (a `Cascade`, or a bare
hysteresis model, `EUPI` or `Preisach`, for rate-free records and non-voltage
inputs) with effect modules.  It reaches the hysteresis only through the
`smafl_jax.models._hysteresis.AbstractHysteresis` protocol (``features`` on a
transformed input, ``linear_weights``) and the effects only through the effect
protocol (`smafl_jax.effects.protocol`): it applies the stages of `STAGES` in
order, each effect through its stage's method, with no effect named here.  The
catalogue's pipeline is

    u --delay--> --sensor_lag--> x --thermal (+ resistance_tc, asymmetric_cooling,
    nonlinear_cooling, ambient_drift)--> u_eff --input_warp--> --EUPI
      (+ rate_dependence)--> H --creep--> (+ strain_accumulation) --output_saturation-->
      --load_dependence--> y

Thermal effects are written on the thermal state in *voltage-squared units*
``q = theta k1 / k2`` (the steady-state value of ``q`` is the applied ``U^2``),
which removes the unidentifiable ``k2`` and gives every effect parameter a
scale: ``q_ref = u_span^2`` of the EUPI.  With ``q`` the base model is

    dq/dt = k1 (U^2 - q),    u_eff = sqrt(q)

and the extended thermal model is

    dq/dt = k1 rho(dir) [ U^2 h(q) - q c(q) + q_amb(t) ]

with ``h = 1 / (1 + beta q / q_ref)`` (resistance_tc), ``c = 1 + gamma q / q_ref``
(nonlinear_cooling), ``rho = exp(log_ratio) / (1 + latent band(q / q_ref))`` while cooling (asymmetric_cooling)
and ``q_amb = drift q_ref t / 1000 s`` (ambient_drift).  It is integrated with
the exact first-order hold of the base model, the nonlinear coefficients frozen
at the previous state (a locally linear step that stays stable for any dt and
reduces to the base model exactly when the effects vanish).

For a bare-EUPI base (temperature input, quasi-static voltage) the thermal
effects do not apply; ``ambient_drift`` then shifts the input by
``drift u_span t / 1000 s``.

``load_dependence`` needs a load signal: ``simulate(u, dt, load=L)``; without
one (``smafl simulate``) the model predicts at its reference load.
"""

from __future__ import annotations

import functools

import equinox as eqx
import jax
import jax.numpy as jnp

from .. import _config  # noqa: F401
from .._io import register_model
from ..models._hysteresis import AbstractHysteresis, hysteresis_of, record_model, thermal_of
from .protocol import EFFECTS, AbstractEffect, effect_rank

__all__ = ["ExtendedModel", "LoadBound"]


@register_model
class ExtendedModel(eqx.Module):
    """Base model (`Cascade` or a hysteresis model) composed with catalogue effects; fitted jointly."""

    #: Not a base for another `ExtendedModel`: effects join this one's tuple instead (`AbstractHysteresis.extendable`).
    extendable = False

    base: eqx.Module
    effects: tuple = ()

    @classmethod
    def of(cls, model) -> ExtendedModel:
        """``model`` as an extended model: itself when it is one already (not `extendable`), else with no effects."""
        return cls(model, ()) if getattr(model, "extendable", True) else model

    def __check_init__(self):
        if not getattr(self.base, "extendable", False) or hysteresis_of(self.base) is None:
            raise ValueError(
                f"ExtendedModel base must be a Cascade or a hysteresis model (EUPI, Preisach), got {type(self.base).__name__}"
            )
        for e in self.effects:
            if not isinstance(e, AbstractEffect):
                raise ValueError(f"unknown effect {type(e).__name__}; catalogue: {list(EFFECTS)}")
        names = [e.name for e in self.effects]
        if len(set(names)) != len(names):
            raise ValueError(f"each effect may appear once, got {names}")
        for e in self.effects:
            if "thermal" in e.needs and thermal_of(self.base) is None:
                raise ValueError(f"effect {e.name!r} acts on the thermal model and needs a Cascade base")
            if e.scales_thresholds and not self.hysteresis.scalable_thresholds:
                raise ValueError(
                    f"effect {e.name!r} scales play thresholds per sample; {type(self.hysteresis).__name__} has none"
                )

    # -- structure -------------------------------------------------------
    @property
    def hysteresis(self) -> AbstractHysteresis:
        return self.base.hysteresis

    @property
    def thermal(self):
        """The base cascade's thermal model (AttributeError for a bare hysteresis base)."""
        return self.base.thermal

    @property
    def linear_in_weights(self) -> bool:
        """True when ``simulate(u, dt) == features(u, dt) @ hysteresis.linear_weights()`` (no load given):
        every effect keeps the output linear in the weights (no output saturation, no strain accumulation)."""
        return all(e.linear_in_weights for e in self.effects)

    @property
    def effect_names(self):
        return [e.name for e in self.effects]

    def get(self, name):
        for e in self.effects:
            if e.name == name:
                return e
        return None

    def stage_effects(self, stage: str) -> list:
        """The effects acting at ``stage``, in catalogue order (the order they act in)."""
        return sorted((e for e in self.effects if e.stage == stage), key=lambda e: effect_rank(e.name))

    def for_record(self, i: int) -> ExtendedModel:
        """The model as it starts record ``i`` of a joint fit (the base's per-record thermal start)."""
        base = record_model(self.base, i)
        return self if base is self.base else eqx.tree_at(lambda m: m.base, self, base)

    def with_hysteresis(self, h):
        """Copy with the hysteresis part replaced."""
        return eqx.tree_at(lambda m: m.base, self, self.base.with_hysteresis(h))

    def trainable_spec(self, *, load: bool = True):
        """Bool PyTree: thermal k1, hysteresis weights and effect parameters train; grids, k2 and the effects'
        `held_fields` (load references) stay.

        ``load=False`` (no load signal, e.g. `smafl_jax.fit` or sampling on a record): effects that then do
        nothing (the load effect) hold their gains too.
        """
        spec = jax.tree_util.tree_map(eqx.is_inexact_array, self)
        fixed = self.hysteresis.fixed_fields()
        spec = eqx.tree_at(lambda s: [getattr(s.hysteresis, f) for f in fixed], spec, [False] * len(fixed))
        if thermal_of(self.base) is not None:  # k2 cancels in the hysteresis input (see `smafl_jax.identify.default_trainable`)
            spec = eqx.tree_at(lambda s: s.base.thermal.k2, spec, False)
        for i, e in enumerate(self.effects):
            held = e.held_fields(load=load)
            if held:
                spec = eqx.tree_at(lambda s: [getattr(s.effects[i], f) for f in held], spec, [False] * len(held))
        return spec

    # -- pipeline --------------------------------------------------------
    def _q_ref(self):
        h = self.hysteresis
        return (h.u_span + h.u_ref) ** 2

    def _q0(self, x):
        th = self.base.thermal
        # q = theta k1/k2, so every init rule of JouleThermal maps over (steady: x0^2, given: u0^2, ambient: 0)
        return th.initial_state(x[0]) * (th.k1 / th.k2)

    def _thermal(self, x, dt):
        """Thermal state in V^2 units ``q`` for drive ``x`` (see module docstring and `AbstractThermalEffect`)."""
        th = self.base.thermal
        k1 = th.k1
        qref = self._q_ref()
        effs = self.stage_effects("thermal")
        n = x.shape[0]
        t = jnp.arange(n, dtype=jnp.float64) * dt
        ambient = [a for a in (e.ambient(t, qref) for e in effs) if a is not None]
        q_amb = functools.reduce(jnp.add, ambient) if ambient else jnp.zeros(n)
        q0 = self._q0(x)
        # U^2 by the base thermal stage's sampling convention, with its slow mode's share when it has one
        heats = th.heat(x, dt)

        def step(q, xs):
            heat, qa = xs
            for e in effs:
                heat = e.heating(heat, q, qref)
            losses = [c for c in (e.loss(q, qref) for e in effs) if c is not None]
            c = functools.reduce(jnp.multiply, losses) if losses else 1.0
            target = heat / c + qa
            rate = k1 * c
            for e in effs:
                rate = e.rate(rate, target, q, qref)
            a = jnp.exp(-rate * dt)
            q = a * q + (1.0 - a) * target
            return q, q

        _, q = jax.lax.scan(step, q0, (heats, q_amb))
        return q

    def hysteresis_input(self, u, dt):
        """Signal the hysteresis sees (after the input-stage effects, the thermal model and its effects)."""
        u = jnp.asarray(u, dtype=jnp.float64)
        dt = jnp.asarray(1.0 if dt is None else dt, dtype=jnp.float64)
        x = u
        for e in self.stage_effects("input"):
            x = e.transform_input(x, dt)
        if thermal_of(self.base) is not None:
            return self.base.drive_of_heat(self._thermal(x, dt))
        effs = self.stage_effects("thermal")
        if effs:
            t = jnp.arange(x.shape[0], dtype=jnp.float64) * dt
            for e in effs:
                x = e.without_thermal(x, t, self.hysteresis)
        return x

    def hysteresis_start(self, u, dt=None):
        """What the hysteresis sees before the first sample (the thermal start state after the input-stage effects);
        None without a thermal stage."""
        if thermal_of(self.base) is None:
            return None
        x = jnp.asarray(u, dtype=jnp.float64)
        dt = jnp.asarray(1.0 if dt is None else dt, dtype=jnp.float64)
        for e in self.stage_effects("input"):
            x = e.transform_input(x, dt)
        return self.base.drive_of_heat(self._q0(x))

    def states(self, u, dt):
        """Internal signals: ``x`` (hysteresis input), ``q`` (thermal state, V^2, cascade only), ``y``."""
        x = self.hysteresis_input(u, dt)
        out = {"x": x, "y": self.simulate(u, dt)}
        if thermal_of(self.base) is not None:
            out["q"] = x * x
        return out

    def features(self, u, dt):
        """Design matrix of the hysteresis weights after the hysteresis-input, threshold and feature stages
        (input warp, rate dependence, creep); linear in the weights."""
        dt = jnp.asarray(1.0 if dt is None else dt, dtype=jnp.float64)
        h = self.hysteresis
        x = self.hysteresis_input(u, dt)
        for e in self.stage_effects("hysteresis_input"):
            x = e.warp(x, h)
        scale = None
        for e in self.stage_effects("hysteresis"):
            s = e.threshold_scale(x, dt, h)
            scale = s if scale is None else scale * s
        F = h.features(x) if scale is None else h.features(x, threshold_scale=scale)
        for e in self.stage_effects("features"):
            F = e.filter_features(F, dt)
        return F

    def linear_columns(self, u, dt):
        """``(T, k)`` output change per unit of each linear effect field, in `linear_column_fields` order (k may be 0)."""
        cols = []
        for e in self.stage_effects("linear"):
            c = e.columns(self, u, dt)
            cols += [c[f] for f in e.linear_fields]
        return jnp.stack(cols, axis=1) if cols else jnp.zeros((jnp.shape(u)[0], 0))

    def linear_column_fields(self) -> list[tuple[str, str]]:
        """``(effect name, field)`` of each column of `linear_columns`."""
        return [(e.name, f) for e in self.stage_effects("linear") for f in e.linear_fields]

    def output_map(self, h, load=None, dt=None):
        """Output-stage effects (saturation, load) applied to the output ``h`` before them."""
        for e in self.stage_effects("output"):
            h = e.output(h, dt, load)
        return h

    def simulate(self, u, dt, load=None):
        """Output for drive ``u`` sampled every ``dt`` s (``load``: optional load signal)."""
        h = self.features(u, dt) @ self.hysteresis.linear_weights()
        for e in self.stage_effects("linear"):
            cols = e.columns(self, u, dt)
            for field in e.linear_fields:
                h = h + getattr(e, field) * cols[field]
        return self.output_map(h, load, dt)


class LoadBound(eqx.Module):
    """An `ExtendedModel` with its load signal attached, so generic fitting sees ``simulate(u, dt)``."""

    model: ExtendedModel
    load: jnp.ndarray

    def simulate(self, u, dt):
        return self.model.simulate(u, dt, load=self.load)

    def for_record(self, i: int) -> LoadBound:
        """The bound model as it starts record ``i`` of a joint fit."""
        return eqx.tree_at(lambda m: m.model, self, record_model(self.model, i))
