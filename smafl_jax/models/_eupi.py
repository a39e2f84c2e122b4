"""Extended unparallel Prandtl-Ishlinskii (EUPI) hysteresis model, eq. (2).

Convention (the paper's index notation is loose; this is the one used here).
The operators act on the normalised input ``s = (u - u_ref) / u_span`` so that
thresholds are fractions of the input span and gains are comparable across
data sets.  With ``u_ref = 0`` this is exactly the paper's model with
thresholds ``r * u_span`` and rescaled gains (play operators are homogeneous:
``F_{c r, a}[c s] = c F_{r, a}[s]``).  The output is

    H(k) = gain * s(k)                                   # G u(k)
         + sum_i v_i     F_{r_sym_i, 1}[s](k)            # symmetric part (CPI)
         + sum_ij w_ij   F_{r_asym_j, alpha_i}[s](k)     # unparallel part (UPI), i: tilt, j: threshold
         + sum_m poly_m  P_(m+2)(s(k))                   # polynomial, m = 0.. (orders 2..Np)
         + offset                                        # p0

with ``P_n(s) = s^n`` on the model's input range ``0 <= s <= 1`` (the paper's powers) and continued
linearly outside it (``1 + n (s - 1)`` above, 0 below: value and slope match at the ends; `poly_columns`).

``gain``, ``v``, ``w`` (and thresholds, tilts) are positive by construction
(see `smafl_jax.positive`); ``poly`` and ``offset`` are free.  The model is
linear in ``(gain, v, w, poly, offset)`` for fixed thresholds and tilts:
`EUPI.features` returns that design matrix, which is what the paper's
constrained least squares (and this toolkit's initialiser) solves.

Initial state (``init``): ``"descended"`` (default) starts every operator on
its upper bound at the first input, the state an actuator is left in after the
previous cycle came down to the starting input, so periodic loops between 0 and
a maximum close on themselves as in the paper's figures; ``"zero"`` starts all
operators at 0 (``F(-1) = 0``, a virgin actuator); ``"consistent"`` is the state
reached when the first input is approached from 0; ``"from_top"`` the state left by
a descent from the top of the model's input range to the first input (an actuator
last driven through its full range); ``"fitted"`` places each
operator at a trained position between its two bounds at the first input
(``memory``: one logit per operator, 0 = midway, large = descended, very
negative = ascended), for records that start on an unknown branch.

Grid rule (`EUPI.from_range`): ``n`` thresholds ``r_i = i / (2 n)``,
i = 1..n, i.e. from ``span/(2n)`` to half the input span (an operator of
threshold >= span/2 can no longer reverse inside the data range); tilts
geometrically spaced in [0.4, 2.5] (both sides of the symmetric tilt 1).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Collection
from types import MappingProxyType

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .. import _config  # noqa: F401
from .._io import register_model
from ._constraints import parameter, positive
from ._hysteresis import AbstractHysteresis, _orientation_line, check_orientation
from ._operators import MODEL_METHODS, consistent_initial_state, play, play_step, play_weighted

__all__ = ["EUPI", "threshold_grid", "tilt_grid", "poly_columns"]


def poly_columns(s, n_poly):
    """Polynomial columns ``P_2(s) .. P_(n_poly+1)(s)``, shape ``s.shape + (n_poly,)``.

    ``P_n(s) = s^n`` for ``0 <= s <= 1`` (the input range the model was built on), continued with its value and
    slope at the ends outside it: ``1 + n (s - 1)`` above, 0 below.  Why: a cubic fitted on one run explodes on a
    new run whose input goes beyond the fitted range (measured on the shared NiTi wire records, whose thermocouple
    spikes to 220 C on one run: single-record EUPI fits missed the other runs by a median 13-66 length units where the
    relay model, bounded by construction, missed by 2.8-3.6).  Inside the range nothing changes.
    """
    k = jnp.arange(2, int(n_poly) + 2, dtype=jnp.float64)
    x = jnp.expand_dims(s, -1)
    k = jnp.reshape(k, (1,) * (x.ndim - 1) + (int(n_poly),))
    inside = jnp.clip(x, 0.0, 1.0) ** k
    return jnp.where(x > 1.0, 1.0 + k * (x - 1.0), jnp.where(x < 0.0, 0.0, inside))


_INITS = ("descended", "zero", "consistent", "fitted", "from_top", "levels")
#: Inits whose state lives in the ``memory`` leaf.
_MEMORY_INITS = ("fitted", "levels")
#: Operator level before the first sample that stands for "descended" in ``init="levels"``: the first step's clamp
#: ``max(lo, min(up, level))`` then gives the upper bound exactly, for any input the model can see.
_ABOVE_ALL = 1e30
#: Start logit of a fitted memory: sigmoid(5) = 0.993 of the way to the descended state, with a gradient left.
DESCENDED_LOGIT = 5.0


def threshold_grid(n: int) -> np.ndarray:
    """Documented threshold rule on the normalised input: ``r_i = i / (2 n)``, i = 1..n."""
    if int(n) < 0:
        raise ValueError(f"number of thresholds must be >= 0, got {n}")
    return np.arange(1, int(n) + 1, dtype=np.float64) / (2.0 * max(int(n), 1))


def tilt_grid(n: int, lo: float = 0.4, hi: float = 2.5) -> np.ndarray:
    """Tilts geometrically spaced in ``[lo, hi]``."""
    if int(n) < 0:
        raise ValueError(f"number of tilts must be >= 0, got {n}")
    if int(n) == 1:
        return np.array([np.sqrt(lo * hi)])
    return np.geomspace(lo, hi, int(n))


def _default_memory(init, n):
    """The ``memory`` leaf a new model of rule ``init`` starts with: near the descended state (fitted logits, or
    levels above every bound), None for the rules that need none."""
    return {"fitted": jnp.full(n, DESCENDED_LOGIT), "levels": jnp.full(n, _ABOVE_ALL)}.get(init)


@register_model
class EUPI(AbstractHysteresis):
    """EUPI hysteresis model (eq. 2) as a PyTree; call `simulate(u)` for the output.

    Final implementation of `AbstractHysteresis` (do not subclass).
    """

    INITS = _INITS
    # "consistent" equals "zero" for a first input at or above u_ref (every input of the default grids)
    RULE_INITS = ("descended", "zero", "from_top")
    #: Operator grid of `from_range` (the ``smafl fit --n-sym / --n-alpha / --n-asym`` defaults): 8 + 4 x 4 operators.
    DEFAULT_GRID = MappingProxyType({"n_sym": 8, "n_alpha": 4, "n_asym": 4})
    #: The sparse grid ``smafl fit --sparse-grid`` adds to ``--model auto``'s candidates behind a drive's thermal lag
    #: (8 operators instead of 24; `smafl_jax.identify.auto_candidates`).  Why: with trained thresholds and tilts the
    #: default grid can fit a record's first 70 % at the noise and miss the rest at 11-14x, two gain solutions the training
    #: part cannot tell apart (session 35); the sparse grid alone held out worse as often as better (30 independent
    #: records, geometric mean 2.49x vs 2.47x the noise), the lower validation RMSE of the two 2.04x (session 43).
    SPARSE_GRID = MappingProxyType({"n_sym": 4, "n_alpha": 2, "n_asym": 2})
    trainable_groups = MappingProxyType({"thresholds": ("r_sym", "r_asym"), "tilts": ("alpha",)})
    scalable_thresholds = True
    evaluation_methods = MODEL_METHODS  # the ``method`` field: scan or an exact parallel-in-time form

    gain: jnp.ndarray = positive()
    v: jnp.ndarray = positive()
    w: jnp.ndarray = positive()
    poly: jnp.ndarray = parameter()
    offset: jnp.ndarray = parameter()
    r_sym: jnp.ndarray = positive()
    r_asym: jnp.ndarray = positive()
    alpha: jnp.ndarray = positive()
    u_ref: jnp.ndarray = parameter()
    u_span: jnp.ndarray = positive()
    # init="fitted": logit of each operator's start between its ascending (lower) and descending (upper)
    # bound at the first input, trained with the gains; init="levels": each operator's output before the
    # first sample (normalised units; the first step clamps it); None for the other init rules
    memory: jnp.ndarray | None = parameter(default=None)
    init: str = eqx.field(static=True, default="descended")
    # evaluation form of the operator bank: "scan" (sequential), "assoc" / "chunked" / "segmented" (exact
    # parallel-in-time forms of smafl_jax.ops, equal to scan bit for bit) or "auto" (choose_model_method)
    method: str = eqx.field(static=True, default="scan")
    # +1: output rises with the operator sum (displacement sensor); -1: falls (length sensor, sensor
    # mounted the other way). The operator gains stay >= 0 either way, so the sign lives here.
    orientation: int = eqx.field(static=True, default=1)

    # Only in `compile_form` (orientation 0): the orientation as data, +1.0 / -1.0, so that the start screening's two
    # output signs share their compiled programs; None in every model a user holds.
    sign: jnp.ndarray | None = eqx.field(default=None, metadata={"transient": True})
    # [lo, hi] the input is held to (`AbstractHysteresis.with_held`; a None side is open); None: the model extrapolates
    held: tuple[float | None, float | None] | None = eqx.field(static=True, default=None)

    def __check_init__(self):
        check_orientation(self, "EUPI")
        if self.init not in _INITS:
            raise ValueError(f"EUPI init must be one of {_INITS}, got {self.init!r}")
        if (self.init in _MEMORY_INITS) != (self.memory is not None):
            raise ValueError(
                "EUPI init='fitted' / 'levels' needs memory (one value per operator), and memory needs one of those inits"
            )
        if self.memory is not None and np.shape(self.memory) != (self.n_operators,):
            raise ValueError(f"memory must have shape ({self.n_operators},), got {np.shape(self.memory)}")
        if self.method not in MODEL_METHODS:
            raise ValueError(f"EUPI method must be one of {MODEL_METHODS}, got {self.method!r}")
        nv, ns = np.shape(self.v), np.shape(self.r_sym)
        if nv != ns:
            raise ValueError(f"v has shape {nv} but r_sym has shape {ns}; they must match")
        wa = (np.shape(self.alpha)[0], np.shape(self.r_asym)[0])
        if np.shape(self.w) != wa:
            raise ValueError(f"w must have shape (len(alpha), len(r_asym)) = {wa}, got {np.shape(self.w)}")

    @classmethod
    def from_range(
        cls,
        u_min,
        u_max,
        *,
        n_sym=8,
        n_alpha=4,
        n_asym=4,
        poly_order=3,
        u_ref=None,
        init="descended",
        method="scan",
        orientation=1,
    ):
        """Untrained EUPI with the documented grids for inputs in ``[u_min, u_max]``.

        ``u_ref`` defaults to ``min(u_min, 0)`` clipped so that voltage-like
        inputs keep the paper's origin; pass ``u_ref=u_min`` for inputs with a
        physical offset (temperature, pressure).  Gains start at zero; fit them.
        """
        u_min, u_max = float(u_min), float(u_max)
        if not np.isfinite(u_min) or not np.isfinite(u_max) or u_max <= u_min:
            raise ValueError(f"input range must be finite with u_max > u_min, got [{u_min}, {u_max}]")
        if int(poly_order) < 1:
            raise ValueError(f"poly_order must be >= 1 (1 = no polynomial terms), got {poly_order}")
        ref = (0.0 if u_min >= 0.0 else u_min) if u_ref is None else float(u_ref)
        span = u_max - ref
        if span <= 0:
            raise ValueError(f"u_ref={ref} must be below u_max={u_max}")
        n_alpha = int(n_alpha) if int(n_asym) > 0 else 0
        return cls(
            gain=jnp.asarray(0.0),
            v=jnp.zeros(int(n_sym)),
            w=jnp.zeros((n_alpha, int(n_asym) if n_alpha else 0)),
            poly=jnp.zeros(int(poly_order) - 1),
            offset=jnp.asarray(0.0),
            r_sym=jnp.asarray(threshold_grid(n_sym)),
            r_asym=jnp.asarray(threshold_grid(n_asym) if n_alpha else np.zeros(0)),
            alpha=jnp.asarray(tilt_grid(n_alpha)),
            u_ref=jnp.asarray(ref),
            u_span=jnp.asarray(span),
            init=init,
            memory=_default_memory(init, int(n_sym) + n_alpha * int(n_asym)),
            method=method,
            orientation=int(orientation),
        )

    # -- structure -------------------------------------------------------
    @property
    def n_operators(self):
        return int(np.shape(self.r_sym)[0] + np.size(self.w))

    def _bank(self):
        n_alpha, n_ra = np.shape(self.w)
        r = jnp.concatenate([self.r_sym, jnp.tile(self.r_asym, n_alpha)])
        a = jnp.concatenate([jnp.ones_like(self.r_sym), jnp.repeat(self.alpha, n_ra)])
        return r, a

    def with_range(self, u_min, u_max, **options):
        """Untrained EUPI with this one's grid sizes and options for inputs in ``[u_min, u_max]``."""
        n_alpha, n_asym = np.shape(self.w)
        kw = dict(
            n_sym=np.shape(self.v)[0], n_alpha=n_alpha, n_asym=n_asym, poly_order=np.shape(self.poly)[0] + 1,
            init=self.init, method=self.method, orientation=self.orientation,
        )  # fmt: skip
        return type(self).from_range(u_min, u_max, **{**kw, **options})

    def with_fitted_memory(self, logit=None) -> EUPI:
        """Copy with ``init="fitted"``: every operator starts at ``sigmoid(logit)`` of the way from its lower
        to its upper bound (default: near the descended state), a trainable ``memory``."""
        logit = DESCENDED_LOGIT if logit is None else logit
        return dataclasses.replace(self, init="fitted", memory=jnp.full(self.n_operators, float(logit)))

    def memory_columns(self, x, fractions):
        """``(columns, C)``: every operator's signed column for each row of start ``fractions`` ``(K, n_operators)``
        (`AbstractHysteresis.memory_columns`), one scan of ``K x n_operators`` operators."""
        return np.arange(1, 1 + self.n_operators), _memory_columns(self, jnp.asarray(x), jnp.asarray(fractions))

    def with_memory_fractions(self, fractions) -> EUPI:
        """Copy with ``init="fitted"`` whose operators start ``fractions`` of the way between their bounds."""
        f = np.clip(np.asarray(fractions, dtype=np.float64), 1e-4, 1.0 - 1e-4)
        if f.shape != (self.n_operators,):
            raise ValueError(f"need one fraction per operator ({self.n_operators}), got shape {f.shape}")
        return dataclasses.replace(self, init="fitted", memory=jnp.asarray(np.log(f / (1.0 - f))))

    def with_init(self, init: str) -> EUPI:
        """Copy started by the rule ``init``; a fitted memory is dropped (its logits belong to ``init="fitted"``)."""
        if init == "fitted":
            return self if self.init == "fitted" else self.with_fitted_memory()
        if init not in _INITS or init == "levels":
            raise ValueError(f"EUPI init must be one of {tuple(i for i in _INITS if i != 'levels')}, got {init!r}")
        return dataclasses.replace(self, init=init, memory=None)

    def screening_form(self, rule: str) -> EUPI:
        """The rule ``rule`` as pre-sample operator levels (``init="levels"``): the same outputs bit for bit, and one
        traced structure for every rule, so the start screening compiles once instead of once per rule."""
        if rule not in self.RULE_INITS:
            raise ValueError(f"EUPI screening rules are {self.RULE_INITS}, got {rule!r}")
        r, _ = self._bank()
        # each rule is "the first step clamps a previous level": above every bound (descended), 0 (a virgin actuator),
        # or the state at the top of the range, 1 - r (a descent from there)
        level = {"descended": jnp.full_like(r, _ABOVE_ALL), "zero": jnp.zeros_like(r), "from_top": 1.0 - r}[rule]
        return dataclasses.replace(self, init="levels", memory=level)

    def with_method(self, method: str) -> EUPI:
        return dataclasses.replace(self, method=method)

    def linear_fields(self):
        return ("gain", "v", "w", "poly", "offset")

    def fixed_fields(self, train: Collection[str] = ()):
        """``u_ref``, ``u_span`` always; thresholds and tilts unless their group is in ``train``."""
        grids = [f for group, names in self.trainable_groups.items() if group not in train for f in names]
        return ("u_ref", "u_span", *grids)

    def nonlinear_priors(self):
        """Thresholds (normalised input) lognormal around the grid's scale 0.25, tilts around 1 (symmetric), and the
        fitted memory's logits normal(0, 4), which keeps walkers off +-inf."""
        return {
            "r_sym": ("lognormal", math.log(0.25), 1.0),
            "r_asym": ("lognormal", math.log(0.25), 1.0),
            "alpha": ("lognormal", 0.0, 1.0),
            "memory": ("normal", 0.0, 4.0),
        }

    def describe(self):
        """Gain, operator counts, polynomial, offset, normalisation, initial state (and fitted memory), orientation."""
        v, w = np.asarray(self.v, dtype=float), np.asarray(self.w, dtype=float)
        lines = [
            f"EUPI: gain {float(self.gain):.4g}, {v.size} symmetric + {w.size} unparallel operators "
            f"({int(np.sum(v > 1e-9) + np.sum(w > 1e-9))} with non-zero gain), "
            f"poly {[round(float(x), 4) for x in np.asarray(self.poly, dtype=float)]}, offset {float(self.offset):.4g}, "
            f"u_ref {float(self.u_ref):g}, u_span {float(self.u_span):g}, init {self.init}"
        ]
        if self.init == "fitted":
            frac = 1.0 / (1.0 + np.exp(-np.asarray(self.memory, dtype=float)))
            lines.append(
                f"operators at t = 0 (fitted memory; 0 = ascended, 1 = descended bound): median {np.median(frac):.2f}, "
                f"range {frac.min():.2f}-{frac.max():.2f}"
            )
        return lines + [_orientation_line(self.orientation), *self.held_lines()]

    def _initial_state(self, s0, r, a):
        if self.init == "descended":
            y0 = a * (s0 + r)  # upper bound at the first input: state left by a descent to u(0)
        elif self.init == "consistent":
            y0 = consistent_initial_state(s0, r, a)
        elif self.init == "from_top":
            # left by a descent from the top of the model's range (s = 1) to the first input: operators whose
            # upper bound lies above 1 - r sit at 1 - r, not at the bound (a descent from far above)
            y0 = jnp.maximum(s0 - r, jnp.minimum(a * (s0 + r), 1.0 - r))
        elif self.init == "fitted":
            lo, up = s0 - r, a * (s0 + r)
            y0 = lo + jax.nn.sigmoid(self.memory) * (up - lo)
        elif self.init == "levels":
            y0 = self.memory
        else:
            y0 = None
        return y0

    def initial_state(self, x0):
        """Operator outputs before the first sample, by the ``init`` rule at the first input ``x0``."""
        r, a = self._bank()
        y0 = self._initial_state(self.normalise(x0), r, a)
        return jnp.zeros_like(r) if y0 is None else y0

    def step(self, state, x):
        """One sample: play step of every operator, then the linear read-out (``features`` row @ weights)."""
        s = self.normalise(x)
        r, a = self._bank()
        ops, _ = play_step(state, s, r, a)
        sign = self.orientation_sign()  # a length sensor reads the operator sum with a minus sign
        powers = poly_columns(s, np.shape(self.poly)[0])
        row = jnp.concatenate([sign * s[None], sign * ops, powers, jnp.ones(1)])
        return ops, row @ self.linear_weights()

    def operators(self, u, threshold_scale=None):
        """Operator outputs ``(T, n_sym + n_alpha * n_asym)`` on the normalised input.

        ``threshold_scale`` (``(T,)``, optional): every threshold multiplied by it at each sample (the
        ``rate_dependence`` effect); the sequential scan is then the only form.
        """
        s = self.normalise(u)
        r, a = self._bank()
        if threshold_scale is None:
            return play(s, r, a, y0=self._initial_state(s[0], r, a), method=self.method)
        y0 = self._initial_state(s[0], r * threshold_scale[0], a)
        y0 = jnp.zeros_like(r) if y0 is None else y0

        def step(carry, xs):
            sk, fk = xs
            rk = r * fk
            y = jnp.maximum(sk - rk, jnp.minimum(a * (sk + rk), carry))
            return y, y

        _, ys = jax.lax.scan(step, y0, (s, threshold_scale))
        return ys

    def features(self, u, dt=None, *, threshold_scale=None):
        """Design matrix ``(T, p)``: columns ``[s, F_sym, F_asym (tilt-major), s^2.., 1]`` (``dt`` ignored)."""
        del dt
        s = self.normalise(u)
        ops = self.operators(u, threshold_scale)
        powers = poly_columns(s, np.shape(self.poly)[0])  # (T, 0) for poly_order=1
        signed = self.orientation_sign() * jnp.concatenate([s[:, None], ops], axis=1)
        return jnp.concatenate([signed, powers, jnp.ones_like(s)[:, None]], axis=1)

    def linear_weights(self):
        """Gains in the column order of `features`."""
        return jnp.concatenate(
            [jnp.reshape(self.gain, (1,)), self.v, jnp.ravel(self.w), self.poly, jnp.reshape(self.offset, (1,))]
        )

    def nonnegative_columns(self):
        """Bool mask over `features` columns whose weights must be >= 0."""
        n_pos = 1 + np.shape(self.v)[0] + np.size(self.w)
        return np.concatenate([np.ones(n_pos, bool), np.zeros(np.shape(self.poly)[0] + 1, bool)])

    def with_linear_weights(self, theta):
        """Copy with gains taken from ``theta`` (column order of `features`)."""
        # concrete gains are split in numpy: the profiled searches set gains hundreds of times per fit, and
        # eager jnp slicing costs a dispatch per piece (1.7 ms -> 0.6 ms per call); traced gains stay jnp
        xp = jnp if isinstance(theta, jax.core.Tracer) else np
        theta = xp.asarray(theta, dtype=np.float64)
        nv, nw, npoly = np.shape(self.v)[0], np.size(self.w), np.shape(self.poly)[0]
        expected = 1 + nv + nw + npoly + 1
        if theta.shape != (expected,):
            raise ValueError(f"expected {expected} linear weights, got shape {theta.shape}")
        parts = (
            theta[0],
            theta[1 : 1 + nv],
            theta[1 + nv : 1 + nv + nw].reshape(np.shape(self.w)),
            theta[1 + nv + nw : 1 + nv + nw + npoly],
            theta[1 + nv + nw + npoly],
        )
        return eqx.tree_at(lambda m: (m.gain, m.v, m.w, m.poly, m.offset), self, tuple(jnp.asarray(p) for p in parts))

    # -- evaluation ------------------------------------------------------
    def simulate(self, u, dt=None):
        """Output for input record ``u`` (1-D). ``dt`` is ignored: the model is rate-independent."""
        del dt
        # Every method goes through smafl_jax.ops with the weights applied per step; for "scan" the
        # weighted sum is inside the scan and writes T numbers instead of T x n (see benchmarks/README.md).
        s = self.normalise(u)
        r, a = self._bank()
        w = jnp.concatenate([self.v, jnp.ravel(self.w)])
        ops = play_weighted(s, r, a, w, y0=self._initial_state(s[0], r, a), method=self.method)
        poly = poly_columns(s, np.shape(self.poly)[0]) @ self.poly
        return self.orientation_sign() * (self.gain * s + ops) + poly + self.offset


@eqx.filter_jit
def _memory_columns(model: EUPI, x, fractions):
    """`EUPI.memory_columns`: the bank repeated once per row of ``fractions``, each copy started at its row."""
    s = model.normalise(x)
    r, a = model._bank()
    k, n = fractions.shape
    lo, up = s[0] - r, a * (s[0] + r)
    y0 = jnp.reshape(lo[None, :] + fractions * (up - lo)[None, :], (k * n,))
    ops = play(s, jnp.tile(r, k), jnp.tile(a, k), y0=y0, method=model.method)
    return model.orientation_sign() * jnp.moveaxis(jnp.reshape(ops, (s.shape[0], k, n)), 1, 0)
