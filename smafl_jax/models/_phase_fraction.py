"""Phase-fraction hysteresis with rescaled reversal branches (``--model phase``): the classical SMA kinetics model.

The contracted (hot) phase fraction ``f`` in [0, 1] follows two major branches of the normalised input
``s = (u - u_ref) / u_span``, logistic in ``s``:

    heating  F_h(s) = sigmoid((s - heat_centre) / heat_width),   cooling  F_c(s) = sigmoid((s - cool_centre) / cool_width),

and after a reversal at ``(s_r, f_r)`` the new branch is the major one rescaled to run from the current point to the
opposite limit (Ikuta, Tsukamoto & Hirose 1991; Likhachev; the rescaling of Liang-Rogers and Brinson kinetics):

    heating: 1 - f = (1 - f_r) (1 - F_h(s)) / (1 - F_h(s_r)),      cooling: f = f_r F_c(s) / F_c(s_r).

Both are products that telescope over the samples of one monotone stretch, so one sample is
``1 - f <- (1 - f) (1 - F_h(s)) / (1 - F_h(s_prev))`` on a rise and ``f <- f F_c(s) / F_c(s_prev)`` on a fall: the
state is ``(f, s_prev)`` (with its branch logs), no reversal point is stored, and the map is rate-independent.  The output is

    y = o * scale * f + gain * s + offset,      scale >= 0,

with ``o`` the orientation; ``scale``, ``gain`` and ``offset`` are the linear weights and the four branch parameters are
trained by the joint refinement.

Why: the play-operator (EUPI) and Preisach classes both have return-point (wiping-out) memory: a minor loop closes
where it started.  An SMA whose reversal curves are rescaled major branches does not: an interrupted heating followed
by cooling and reheating ends on another curve, and every class with wiping-out memory then misfits even the training
record (the second independent plant's rescaled-branch records trained at 8-21x the noise, session 46).  Four shape
parameters also identify the branches from a short record, where a free operator grid leaves the operators the record
never moved arbitrary.

Start: the start screening runs on a free relay grid (`screening_grid`: `Preisach`) shared with the Preisach classes;
the moments of the screened weights' switch-up and switch-down levels give the branches (`adopt`), beside a few broad
shapes.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Collection

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .. import _config  # noqa: F401
from .._io import register_model
from ._constraints import parameter, positive
from ._hysteresis import AbstractScaledShape, _orientation_line, check_orientation
from ._preisach import Preisach

__all__ = ["PhaseFraction"]

_INITS = ("descended", "zero")
#: Smallest branch width (normalised input): a narrower logistic is a step the refinement cannot move smoothly.
MIN_WIDTH = 0.005
#: Broad branch starts of `PhaseFraction.adopt` (heating centre, cooling centre; normalised input), width 0.08 each.
START_BRANCHES = ((0.6, 0.4), (0.75, 0.5), (0.45, 0.25), (0.8, 0.3))
#: logistic sd = width * pi / sqrt(3): converts a screened level spread into a logistic width
_SD_TO_WIDTH = math.sqrt(3.0) / math.pi


@register_model
class PhaseFraction(AbstractScaledShape):
    """Phase fraction on logistic major branches, reversal branches rescaled to the opposite limit (module docstring).

    Final implementation of `AbstractHysteresis` (do not subclass).
    """

    INITS = _INITS
    RULE_INITS = _INITS

    scale: jnp.ndarray = positive()  # output change from fraction 0 to fraction 1
    gain: jnp.ndarray = parameter()  # linear term on s (reversible: thermal expansion, elastic stretch); either sign
    offset: jnp.ndarray = parameter()
    heat_centre: jnp.ndarray = parameter()  # normalised input at half transformation on the heating major branch
    heat_width: jnp.ndarray = positive()
    cool_centre: jnp.ndarray = parameter()
    cool_width: jnp.ndarray = positive()
    u_ref: jnp.ndarray = parameter()
    u_span: jnp.ndarray = positive()
    init: str = eqx.field(static=True, default="descended")
    orientation: int = eqx.field(static=True, default=1)

    # Only in `compile_form` (orientation 0): the orientation as data (`AbstractHysteresis.compile_form`).
    sign: jnp.ndarray | None = eqx.field(default=None, metadata={"transient": True})
    # [lo, hi] the input is held to (`AbstractHysteresis.with_held`; a None side is open); None: the model extrapolates
    held: tuple[float | None, float | None] | None = eqx.field(static=True, default=None)

    def __check_init__(self):
        check_orientation(self, "PhaseFraction")
        if self.init not in _INITS:
            raise ValueError(f"PhaseFraction init must be one of {_INITS}, got {self.init!r}")
        for name in ("scale", "gain", "offset", "heat_centre", "heat_width", "cool_centre", "cool_width", "u_ref", "u_span"):
            if np.shape(getattr(self, name)) != ():
                raise ValueError(f"PhaseFraction {name} must be a scalar, got shape {np.shape(getattr(self, name))}")

    # -- construction ------------------------------------------------------------------------------------------------
    @classmethod
    def from_range(cls, u_min, u_max, *, init="descended", orientation=1):
        """Untrained model for inputs in ``[u_min, u_max]``: heating branch centred at 60 %, cooling at 40 % of the
        range, both 8 % wide."""
        u_min, u_max = float(u_min), float(u_max)
        if not np.isfinite(u_min) or not np.isfinite(u_max) or u_max <= u_min:
            raise ValueError(f"input range must be finite with u_max > u_min, got [{u_min}, {u_max}]")
        return cls(
            scale=0.0, gain=0.0, offset=0.0, heat_centre=0.6, heat_width=0.08, cool_centre=0.4, cool_width=0.08,
            u_ref=u_min, u_span=u_max - u_min, init=init, orientation=int(orientation),
        )  # fmt: skip

    def with_range(self, u_min, u_max, **options):
        """Untrained model with this one's options for inputs in ``[u_min, u_max]``."""
        return type(self).from_range(u_min, u_max, **{"init": self.init, "orientation": self.orientation, **options})

    def screening_grid(self):
        """A free relay grid (`Preisach`, its screening levels) over this range, shared with the Preisach classes: its
        non-negative weights rank the start candidates, and their switch levels start the branches (`adopt`)."""
        lo, hi = float(self.u_ref), float(self.u_ref + self.u_span)
        return Preisach.from_range(lo, hi, n_levels=Preisach.SCREEN_LEVELS, init=self.init, orientation=self.orientation)

    def adopt(self, screened):
        """Starts of the branches with ``screened``'s range, orientation and initial-state rule: the weighted mean and
        spread of the screened relays' switch-up (heating) and switch-down (cooling) levels, then the broad
        `START_BRANCHES` (the moments of a sparse non-negative solution can miss the basin)."""
        lo, span = float(screened.u_ref), float(screened.u_span)
        out = self.with_range(lo, lo + span, init=screened.init, orientation=screened.orientation)
        starts = [dict(heat_centre=h, heat_width=0.08, cool_centre=c, cool_width=0.08) for h, c in START_BRANCHES]
        w = np.clip(np.asarray(getattr(screened, "w", ()), dtype=float), 0.0, None)
        if hasattr(screened, "thresholds") and np.size(w) > 0:
            a, b = (np.asarray(t, dtype=float) for t in screened.thresholds())
            w = np.where(a > b, w, 0.0)  # the diagonal relays are reversible steps: the linear term carries them
            if np.sum(w) > 0:
                p = w / w.sum()
                a, b = (a - lo) / span, (b - lo) / span
                ma, mb = float(p @ a), float(p @ b)
                wa = max(_SD_TO_WIDTH * math.sqrt(float(p @ (a - ma) ** 2)), 2 * MIN_WIDTH)
                wb = max(_SD_TO_WIDTH * math.sqrt(float(p @ (b - mb) ** 2)), 2 * MIN_WIDTH)
                starts.insert(0, dict(heat_centre=ma, heat_width=wa, cool_centre=mb, cool_width=wb))
        return tuple(dataclasses.replace(out, **{k: jnp.asarray(v, dtype=jnp.float64) for k, v in s.items()}) for s in starts)

    # -- structure ---------------------------------------------------------------------------------------------------
    def fixed_fields(self, train: Collection[str] = ()):
        """The normalisation; the branches are always trained."""
        del train
        return ("u_ref", "u_span")

    def nonlinear_priors(self):
        """Branch centres normal around 60 % / 40 % of the range, widths lognormal around 8 % (normalised input)."""
        return {
            "heat_centre": ("normal", 0.6, 0.5),
            "cool_centre": ("normal", 0.4, 0.5),
            "heat_width": ("lognormal", math.log(0.08), 1.0),
            "cool_width": ("lognormal", math.log(0.08), 1.0),
        }

    def _log_branches(self, s):
        """``(log(1 - F_h(s)), log F_c(s))``, computed stably for any ``s``."""
        zh = (s - self.heat_centre) / (self.heat_width + MIN_WIDTH)
        zc = (s - self.cool_centre) / (self.cool_width + MIN_WIDTH)
        return jax.nn.log_sigmoid(-zh), jax.nn.log_sigmoid(zc)

    # -- state rule --------------------------------------------------------------------------------------------------
    def initial_state(self, x0):
        """``(f, s, log(1 - F_h(s)), log F_c(s))`` at the first input: on the cooling major branch (``descended``: the
        input came down from above the range) or on the heating one (``zero``: it rose from below, every relay of a
        Preisach down).  The branch logs of the last input ride along so that each sample evaluates them once."""
        s0 = self.normalise(x0)
        lh, lc = self._log_branches(s0)
        f0 = jnp.exp(lc) if self.init == "descended" else -jnp.expm1(lh)
        return f0, s0, lh, lc

    def _advance(self, state, x):
        f, sp, lh0, lc0 = state
        s = self.normalise(x)
        lh, lc = self._log_branches(s)
        # the branch not taken may have a positive log ratio: capped at 0 so that its exp never overflows (the taken
        # branch's ratio is <= 0 by monotonicity, so the cap never changes it)
        rise = 1.0 - (1.0 - f) * jnp.exp(jnp.minimum(lh - lh0, 0.0))
        fall = f * jnp.exp(jnp.minimum(lc - lc0, 0.0))
        f = jnp.where(s > sp, rise, jnp.where(s < sp, fall, f))
        return (f, s, lh, lc), f

    def step(self, state, x):
        """One sample: the fraction moved along the branch of the input's direction, then the read-out."""
        state, f = self._advance(state, x)
        return state, self.read_out(f, x)

    def shape(self, u):
        """Phase fraction per sample (one scan)."""
        u = jnp.asarray(u, dtype=jnp.float64)
        _, f = jax.lax.scan(lambda state, x: self._advance(state, x), self.initial_state(u[0]), u)
        return f

    def describe(self):
        """Scale, linear term, the two branches in input units, initial state, orientation."""
        span = float(self.u_span)
        to_u = lambda s: float(self.u_ref) + span * float(s)
        width = lambda w: span * (float(w) + MIN_WIDTH)
        return [
            f"PhaseFraction: scale {float(self.scale):.4g}, linear gain {float(self.gain):.4g}, offset {float(self.offset):.4g}; "
            f"heating branch centre {to_u(self.heat_centre):.4g} (width {width(self.heat_width):.3g}), cooling branch "
            f"centre {to_u(self.cool_centre):.4g} (width {width(self.cool_width):.3g}); reversal branches rescaled to the "
            f"opposite limit; input range [{float(self.u_ref):g}, {float(self.u_ref) + span:g}], init {self.init}",
            _orientation_line(self.orientation),
            *self.held_lines(),
        ]
