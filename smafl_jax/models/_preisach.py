"""Discrete Preisach hysteresis model (issue 6, ``nonlocal_memory``).

A relay (hysteron) ``R_ab`` with switch-up threshold ``a >= b`` (switch-down)
outputs 1 once ``u >= a``, 0 once ``u <= b`` and otherwise keeps its state.
The model output is

    y(k) = sum_ab w_ab R_ab[u](k) + gain * s(k) [if linear] + offset,   w_ab >= 0,

with ``s = (u - u_ref) / u_span``.  The relays sit on the triangular grid of
``n`` levels ``L_0 < ... < L_{n-1}``: ``(a, b) = (L_i, L_j)``, ``i >= j``, so
``n (n + 1) / 2`` weights (flattened in ``np.tril_indices(n)`` order).  The
diagonal ``i == j`` relays are reversible steps.  `Preisach.from_range` puts the
levels at the centres of ``n`` equal cells of ``[u_min, u_max]``, so no level
lies on a range end (a relay there would duplicate the offset).

Why: a Preisach model has return-point (wiping-out) memory but, unlike
play-operator (PI/EUPI) models, no congruency constraint on its minor loops;
first-order reversal curves (FORCs) are exactly the data it is identified
from, and held-out FORCs are predicted by interpolating the weight density.
The model is linear in the weights: `fit_preisach` solves the bounded least
squares with a Tikhonov (first differences of neighbouring grid weights) and
ridge penalty, and reports the effective degrees of freedom ``trace(H)``.

Ramp relays (``width`` > 0, the default of `Preisach.from_range`: one cell):
a relay's thresholds are spread uniformly over ``width``, so its state is a
fraction in ``[0, 1]``: ``r <- max(min(r, S((u - b) / width)), S((u - a) / width))``
with ``S(x) = clip(x + 1/2, 0, 1)``.  The output is then continuous in the
input (no staircase between levels; a crisp relay grid misses new data whose
input falls between the training levels by up to one level's jump), keeps
return-point memory, is still linear in the weights, and equals the crisp
relay grid whenever the input sits on a cell edge (``width`` = cell width).
``width = 0`` gives crisp relays.

Initial state (``init``): ``"descended"`` (default) is the state after the
input came down from above ``u_max`` to ``u(0)`` (relays with ``b < u(0)`` up,
like the EUPI's default); ``"zero"`` starts every relay down (virgin state).
For a record starting at the bottom of the range (``u(0) <= L_0``, e.g. 0 V)
both coincide: every relay is down.

Orientation (``orientation``, like the EUPI's): with ``-1`` the relay sum and
the linear term enter with a minus sign (a length sensor, whose reading falls
as the actuator contracts); the weights stay >= 0 either way.
"""

from __future__ import annotations

from collections.abc import Collection

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .. import _config  # noqa: F401
from .._io import register_model
from .._progress import Steps, say
from ._constraints import as_float_array, positive
from ._hysteresis import AbstractHysteresis, check_orientation
from ._padding import padded_call

__all__ = [
    "Preisach",
    "preisach_levels",
    "tikhonov_matrix",
    "fit_preisach",
    "cv_fit_preisach",
    "relay_loop",
    "everett_weights",
    "fit_everett",
    "forc_shaped",
]

_INITS = ("descended", "zero")


def preisach_levels(u_min, u_max, n_levels):
    """Cell-centred levels ``u_min + (i + 1/2) (u_max - u_min) / n``, i = 0..n-1."""
    n = int(n_levels)
    if n < 1:
        raise ValueError(f"n_levels must be >= 1, got {n_levels}")
    h = (float(u_max) - float(u_min)) / n
    return float(u_min) + (np.arange(n) + 0.5) * h


@eqx.filter_jit
def _relay_scan(a, b, width, r0, u, weights):
    """The relay recurrence over ``u`` from states ``r0``: per step the states (``weights`` None) or their weighted sum.

    A module-level jitted function, not a closure made per call: called outside a jitted caller (the cross-validated
    fits, the diagnosis' design matrices) a fresh step function recompiled the scan on every call (28 compilations of one
    program in a default fit of a 30 000-sample record).
    """

    def step(r, uk):
        lo, hi = _switch_fractions(uk, a, b, width)
        # up wins on a tie (crisp a == b relays are reversible steps: 1 iff u >= a)
        r = jnp.maximum(jnp.minimum(r, hi), lo)
        return r, (r if weights is None else r @ weights)

    _, out = jax.lax.scan(step, r0, u)
    return out


@register_model
class Preisach(AbstractHysteresis):
    """Discrete Preisach model on a triangular relay grid; `simulate(u)` gives the output.

    Final implementation of `AbstractHysteresis` (do not subclass).
    """

    INITS = _INITS
    RULE_INITS = _INITS
    #: The relay weights are solved exactly (non-negative least squares) at every profiled start; the joint LM over
    #: softplus weights ended at or above that start, or was rejected on validation, on 5 of 6 records of the second
    #: independent plant after up to 300 steps (session 20, experiments/results/plant_b_probes.jsonl).
    refine_jointly = False
    #: Not among ``--model auto``'s candidates behind the thermal lag since the rescaled-branch class joined (session
    #: 54): it shares the Gaussian Preisach's start screening, and on 36 fresh independent records with four classes
    #: (plant B seeds 30-37, plant A matrix seed 30 and random levels seeds 30-32; per-class fits in
    #: experiments/results/class_choice_phase_session54/) auto without it held out 2.88x the noise (geometric mean; 13
    #: within 1.5x, 24 within 3x) against 3.39x (12, 21) with it; on the 60 stored three-class fits of sessions 27-28
    #: leaving it out changed one group (plant B seeds 12-15: 21.7x -> 22.4x).  Its finish cost 8 s of the benchmark
    #: fit's 2-core time.  On a directly measured input (temperature, pressure) it is still compared.
    compared_behind_lag = False
    #: Levels behind a cascade's thermal lag (the default grid): 12 levels held out 2.7-13.5x the noise on plant-B
    #: records where 24 held out 1.4-3.8x (session 20).
    CASCADE_LEVELS = 24
    #: Levels of the start screening's candidates (`screening_grid`): each candidate profiles the relay weights over a
    #: grid of thermal rates, and the non-negative least squares of 300 relays made the screening 2-3x slower than the
    #: rest of the fit; the chosen start is finished on the full grid.
    SCREEN_LEVELS = 12

    w: jnp.ndarray = positive()  # (n (n+1) / 2,) relay weights, np.tril_indices(n) order (i: up level, j: down level)
    offset: jnp.ndarray
    gain: jnp.ndarray  # linear term on s (only used if ``linear``)
    levels: jnp.ndarray  # (n,) increasing relay thresholds
    u_ref: jnp.ndarray
    u_span: jnp.ndarray = positive()
    # ramp width of every relay in input units; 0 = crisp relays (the default, so models saved before ramps load unchanged)
    width: jnp.ndarray = eqx.field(default=0.0, converter=as_float_array)
    init: str = eqx.field(static=True, default="descended")
    linear: bool = eqx.field(static=True, default=False)
    # +1: output rises with the relay sum; -1: falls (length sensor). Default +1: models saved before load unchanged.
    orientation: int = eqx.field(static=True, default=1)

    # Only in `compile_form` (orientation 0): the orientation as data, +1.0 / -1.0, so that the start screening's two
    # output signs share their compiled programs; None in every model a user holds.
    sign: jnp.ndarray | None = eqx.field(default=None, metadata={"transient": True})
    # [lo, hi] the input is held to (`AbstractHysteresis.with_held`; a None side is open); None: the model extrapolates
    held: tuple[float | None, float | None] | None = eqx.field(static=True, default=None)

    def __check_init__(self):
        check_orientation(self, "Preisach")
        if self.init not in _INITS:
            raise ValueError(f"Preisach init must be one of {_INITS}, got {self.init!r}")
        nl = np.shape(self.levels)
        if len(nl) != 1 or nl[0] < 1:
            raise ValueError(f"levels must be a non-empty 1-D array, got shape {nl}")
        m = nl[0] * (nl[0] + 1) // 2
        if np.shape(self.w) != (m,):
            raise ValueError(f"w must have shape (n(n+1)/2,) = ({m},) for {nl[0]} levels, got {np.shape(self.w)}")
        if np.shape(self.width) != ():
            raise ValueError(f"width must be a scalar, got shape {np.shape(self.width)}")
        if not isinstance(self.width, jax.core.Tracer) and not float(self.width) >= 0.0:
            raise ValueError(f"width must be >= 0 (0 = crisp relays), got {float(self.width)}")

    @classmethod
    def from_range(cls, u_min, u_max, *, n_levels=24, linear=False, init="descended", ramp=True, orientation=1):
        """Untrained model with ``n_levels`` cell-centred levels over ``[u_min, u_max]`` (weights zero; fit them).

        ``ramp=True`` spreads each relay over its cell (``width`` = cell width):
        continuous output, identical to crisp relays on inputs at cell edges.
        """
        u_min, u_max = float(u_min), float(u_max)
        if not np.isfinite(u_min) or not np.isfinite(u_max) or u_max <= u_min:
            raise ValueError(f"input range must be finite with u_max > u_min, got [{u_min}, {u_max}]")
        lv = preisach_levels(u_min, u_max, n_levels)
        n = lv.size
        return cls(
            w=jnp.zeros(n * (n + 1) // 2),
            offset=jnp.asarray(0.0),
            gain=jnp.asarray(0.0),
            levels=jnp.asarray(lv),
            u_ref=jnp.asarray(u_min),
            u_span=jnp.asarray(u_max - u_min),
            width=jnp.asarray((u_max - u_min) / n if ramp else 0.0),
            init=init,
            linear=bool(linear),
            orientation=int(orientation),
        )

    def screening_grid(self):
        """This model on `SCREEN_LEVELS` levels (itself when its grid is no finer)."""
        if self.n_levels <= self.SCREEN_LEVELS:
            return self
        return self.with_range(float(self.u_ref), float(self.u_ref + self.u_span), n_levels=self.SCREEN_LEVELS)

    def on_grid_of(self, fine):
        """This model's range, ``init``, orientation and options with ``fine``'s number of levels (weights zero)."""
        if fine.n_levels == self.n_levels:
            return self
        return self.with_range(float(self.u_ref), float(self.u_ref + self.u_span), n_levels=fine.n_levels)

    @classmethod
    def for_cascade(cls, u_max):
        """Untrained relay grid over ``[0, u_max]`` with `CASCADE_LEVELS` levels."""
        return cls.from_range(0.0, u_max, n_levels=cls.CASCADE_LEVELS)

    def with_range(self, u_min, u_max, **options):
        """Untrained grid with this one's size and options for inputs in ``[u_min, u_max]``."""
        kw = dict(
            n_levels=self.n_levels, linear=self.linear, init=self.init, ramp=bool(float(self.width) > 0),
            orientation=self.orientation,
        )  # fmt: skip
        return type(self).from_range(u_min, u_max, **{**kw, **options})

    # -- structure -------------------------------------------------------
    @property
    def n_levels(self):
        return int(np.shape(self.levels)[0])

    @property
    def n_relays(self):
        return int(np.shape(self.w)[0])

    def thresholds(self):
        """``(a, b)``: switch-up and switch-down thresholds of every relay (``a >= b``)."""
        i, j = np.tril_indices(self.n_levels)
        return self.levels[i], self.levels[j]

    def linear_fields(self):
        return ("w", "offset", "gain") if self.linear else ("w", "offset")

    def weight_scales(self):
        """Relays share the output: ``1 / sqrt(n_relays)`` each, so the whole bank has the scale of one gain."""
        return {"w": 1.0 / np.sqrt(self.n_relays), "offset": 1.0, "gain": 1.0}

    def fixed_fields(self, train: Collection[str] = ()):
        """The grid (levels, span, ramp width) and, without a linear term, its unused gain."""
        del train  # no optional groups: the grid is chosen by cross-validation, not trained
        return ("levels", "u_ref", "u_span", "width") + (() if self.linear else ("gain",))

    def initial_state(self, x0):
        """Relay states before the first sample: all up (``descended``; the first sample then switches the
        relays above it down) or all down (``zero``)."""
        del x0
        a, _ = self.thresholds()
        return jnp.ones_like(a) if self.init == "descended" else jnp.zeros_like(a)

    def step(self, state, x):
        """One sample: every relay switched by ``x``, then the weighted read-out."""
        a, b = self.thresholds()
        lo, hi = _switch_fractions(self.seen(x), a, b, self.width)
        r = jnp.maximum(jnp.minimum(state, hi), lo)
        o = self.orientation_sign()
        y = o * (r @ self.w) + self.offset
        if self.linear:
            y = y + o * self.gain * self.normalise(x)
        return r, y

    def _scan(self, u, weights=None):
        """One scan over the input; per step the relay states (``weights=None``) or their weighted sum."""
        u = self.seen(u)
        a, b = self.thresholds()
        return _relay_scan(a, b, self.width, self.initial_state(u[0]), u, weights)

    def relays(self, u):
        """Relay states ``(T, n_relays)`` in ``[0, 1]`` (in {0, 1} for crisp relays)."""
        return self._scan(u)

    def features(self, u, dt=None):
        """Design matrix ``(T, p)``: columns ``[relays, s (if linear), 1]`` (linear in the weights; ``dt`` ignored)."""
        del dt
        o = self.orientation_sign()
        R = self._scan(u)
        s = self.normalise(u)
        cols = [o * R] + ([o * s[:, None]] if self.linear else []) + [jnp.ones_like(s)[:, None]]
        return jnp.concatenate(cols, axis=1)

    def linear_weights(self):
        """Weights in the column order of `features`."""
        parts = [self.w] + ([jnp.reshape(self.gain, (1,))] if self.linear else []) + [jnp.reshape(self.offset, (1,))]
        return jnp.concatenate(parts)

    def nonnegative_columns(self):
        """Bool mask over `features` columns whose weights must be >= 0 (relays, linear gain)."""
        return np.concatenate([np.ones(self.n_relays + int(self.linear), bool), np.zeros(1, bool)])

    def with_linear_weights(self, theta):
        """Copy with weights taken from ``theta`` (column order of `features`)."""
        theta = jnp.asarray(theta, dtype=jnp.float64)
        m = self.n_relays
        expected = m + int(self.linear) + 1
        if theta.shape != (expected,):
            raise ValueError(f"expected {expected} linear weights, got shape {theta.shape}")
        gain = theta[m] if self.linear else self.gain
        return eqx.tree_at(lambda p: (p.w, p.gain, p.offset), self, (theta[:m], gain, theta[-1]))

    # -- evaluation ------------------------------------------------------
    def simulate(self, u, dt=None):
        """Output for input record ``u`` (1-D). ``dt`` is ignored: the model is rate-independent."""
        del dt
        o = self.orientation_sign()
        y = o * self._scan(u, self.w) + self.offset
        if self.linear:
            y = y + o * self.gain * self.normalise(u)
        return y


def _switch_fractions(u, a, b, width):
    """Per relay at input ``u``: the fraction forced up (``lo``, by the up threshold) and allowed up (``hi``)."""
    positive_width = width > 0
    safe = jnp.where(positive_width, width, 1.0)  # no 0/0 in the untaken branch (its gradient would be NaN)
    ramp = lambda t: jnp.clip((u - t) / safe + 0.5, 0.0, 1.0)
    lo = jnp.where(positive_width, ramp(a), (u >= a).astype(u.dtype))
    hi = jnp.where(positive_width, ramp(b), (u > b).astype(u.dtype))
    return lo, hi


def relay_loop(u, a, b, init_up, width=0.0):
    """Plain numpy reference of the relay bank (tests): states ``(T, n)``; ``width > 0`` gives ramp relays."""
    r = np.ones(len(a)) if init_up else np.zeros(len(a))
    out = np.empty((len(u), len(a)))
    for k, uk in enumerate(u):
        for m in range(len(a)):
            if width == 0:
                if uk >= a[m]:
                    r[m] = 1.0
                elif uk <= b[m]:
                    r[m] = 0.0
            else:
                forced_up = min(max((uk - a[m]) / width + 0.5, 0.0), 1.0)
                allowed_up = min(max((uk - b[m]) / width + 0.5, 0.0), 1.0)
                r[m] = max(min(r[m], allowed_up), forced_up)
        out[k] = r
    return out


def tikhonov_matrix(n):
    """First differences of neighbouring grid weights (along the up and the down level), ``(n_pairs, n(n+1)/2)``."""
    i, j = np.tril_indices(n)
    index = {(ii, jj): k for k, (ii, jj) in enumerate(zip(i, j))}
    rows = []
    for (ii, jj), k in index.items():
        for nb in ((ii + 1, jj), (ii, jj + 1)):
            if nb in index:
                rows.append((k, index[nb]))
    D = np.zeros((len(rows), len(index)))
    for r, (k, m) in enumerate(rows):
        D[r, k], D[r, m] = -1.0, 1.0
    return D


_features_jit = eqx.filter_jit(lambda m, u: m.features(u))


def design(model, segments):
    """Stacked features and targets of ``segments`` (each ``(u, y)`` or ``(u, y, mask)``; each simulated from its start)."""
    rows, ys = [], []
    for seg in segments:
        u, y, mask = _as_seg(seg)
        F = padded_call(_features_jit, model, (np.asarray(u, dtype=np.float64),))  # few lengths, few compilations
        rows.append(F[mask])
        ys.append(np.asarray(y, float)[mask])
    return np.concatenate(rows), np.concatenate(ys)


def solve_penalised(A, y, nonneg, P, lam, *, dof=True):
    """``min ||A x - y||^2 + lam x' P x`` s.t. ``x[nonneg] >= 0`` (`smafl_jax.identify.linear.solve`, method "nnls").

    Unbounded columns enter NNLS twice (``x = x+ - x-``).  Lawson-Hanson NNLS
    gives the same minimiser as scipy's BVLS here, about 25x faster on a
    631-relay grid (the inner CV solves it hundreds of times).
    Returns ``(x, dof)`` with ``dof = trace(H)``, the hat matrix restricted to
    the free (non-clamped) columns: the effective number of parameters
    (``dof=False``: None, skipping its solve, e.g. in the cross-validation cells).
    """
    from ..identify.linear import solve

    # unscaled columns (the smoothness penalty couples neighbouring weights in their own units), jitter 1e-10
    sol = solve(A, y, nonneg, penalty=lam * P, scale=False, jitter=1e-10, method="nnls", clip=False, dof=dof)
    return sol.x, sol.dof


def penalty_matrix(model, smooth, ridge=0.0):
    """``P`` over the feature columns: ``smooth * D'D + ridge * I`` on the relay weights (columns scaled per level count)."""
    n, m = model.n_levels, model.n_relays
    p = m + int(model.linear) + 1
    D = tikhonov_matrix(n)
    P = np.zeros((p, p))
    P[:m, :m] = smooth * (D.T @ D) + ridge * np.eye(m)
    return P


def fit_preisach(model, segments, *, lam=1e-2, ridge=0.0):
    """Weights of ``model`` by penalised bounded least squares on ``segments``; returns ``(model, info)``.

    The penalty is ``lam * n_rows * (||D w||^2 + ridge ||w||^2)`` with ``D``
    the first differences of neighbouring grid weights, so ``lam`` is per
    sample (comparable across record lengths).
    """
    A, y = design(model, segments)
    P = penalty_matrix(model, 1.0, ridge) * (lam * A.shape[0])
    x, dof = solve_penalised(A, y, model.nonnegative_columns(), P, 1.0)
    fitted = model.with_linear_weights(jnp.asarray(x))
    res = A @ x - y
    return fitted, {
        "sse": float(res @ res),
        "n": int(A.shape[0]),
        "dof": dof,
        "lam": lam,
        "ridge": ridge,
        "n_levels": model.n_levels,
        "width": float(model.width),
        "n_nonzero": int(np.sum(x[: model.n_relays] > 0)),
    }


#: Interpolants of the measured FORC surface in the reversal input (`everett_weights`).
EVERETT_INTERPOLANTS = ("spline", "pchip", "linear")


def forc_shaped(segments, rtol=1e-9, start_tol=0.01):
    """True for first-order reversal curves: every segment starts at the bottom of the common input range
    (within ``start_tol`` of it, so all relays start down), rises monotonically to its maximum, then falls monotonically."""
    us = [np.asarray(_as_seg(seg)[0], float) for seg in segments]
    if len(us) < 2 or any(u.size < 2 for u in us):
        return False
    bottom = min(float(u.min()) for u in us)
    span = max(float(u.max()) for u in us) - bottom
    for u in us:
        k = int(np.argmax(u))
        tol = rtol * max(span, 1e-300)
        if u[0] - bottom > start_tol * span or np.any(np.diff(u[: k + 1]) < -tol) or np.any(np.diff(u[k:]) > tol):
            return False
    return True


def everett_weights(segments, levels, interp="spline"):
    """Relay weights and offset of the Preisach grid (cell-centred ``levels``) whose FORCs are the measured ones.

    Classical FORC (Everett) identification: the surface ``F(a, b)``, the output
    after rising to ``a`` and falling to ``b``, is read off the measured branches
    (linear in ``b`` between samples), interpolated in the reversal input ``a``
    (``interp``: natural cubic ``spline``, ``pchip`` or ``linear``; the rising
    major branch gives the diagonal ``F(b, b)``) at the level-cell edges, and the
    relay weights are its mixed second differences.  The grid then reproduces
    every measured FORC at the cell edges; weights may be negative where the data
    break the nonnegative-density (congruency-free) Preisach structure.
    """
    from scipy.interpolate import CubicSpline, PchipInterpolator

    if interp not in EVERETT_INTERPOLANTS:
        raise ValueError(f"interp must be one of {EVERETT_INTERPOLANTS}, got {interp!r}")
    segs = [_as_seg(s) for s in segments]
    if not forc_shaped(segs):
        raise ValueError(
            "Everett identification needs first-order reversal curves: each segment rising to its maximum, then falling"
        )
    lv = np.asarray(levels, float)
    n = lv.size
    h = (lv[-1] - lv[0]) / (n - 1) if n > 1 else 1.0
    edges = np.concatenate([[lv[0] - h / 2], lv + h / 2])
    mu, my, _ = max(segs, key=lambda sg: float(np.max(sg[0])))
    k = int(np.argmax(mu))
    rising = (np.asarray(mu, float)[: k + 1], np.asarray(my, float)[: k + 1])
    forcs = []
    for u, y, _ in segs:
        u, y = np.asarray(u, float), np.asarray(y, float)
        i = int(np.argmax(u))
        forcs.append((float(u[i]), u[i:][::-1], y[i:][::-1]))
    forcs.sort(key=lambda t: t[0])
    F = np.zeros((n + 1, n + 1))  # F[p, q]: risen to edge p, fallen to edge q <= p
    for q in range(n + 1):
        b = edges[q]
        xs, vs = [b], [float(np.interp(b, *rising))]
        for a, du, dy in forcs:
            if a > xs[-1] + 1e-9 * h:
                xs.append(a)
                vs.append(float(np.interp(b, du, dy)))
        xs, vs = np.array(xs), np.array(vs)
        at = np.minimum(edges[q:], xs[-1])  # above the largest reversal the top branch holds
        if xs.size >= 3 and interp == "spline":
            F[q:, q] = CubicSpline(xs, vs, bc_type="natural")(at)
        elif xs.size >= 3 and interp == "pchip":
            F[q:, q] = PchipInterpolator(xs, vs)(at)
        else:
            F[q:, q] = np.interp(at, xs, vs)
    # relay (i, j) is up after rising to edge p and falling to edge q iff i < p and j < q: F = offset + cumulative sums
    i, j = np.tril_indices(n)
    Fi = lambda p, q: F[p, np.minimum(q, p)]
    w = Fi(i + 1, j + 1) - Fi(i + 1, j) - Fi(i, j + 1) + Fi(i, j)
    return w, float(F[0, 0])


def fit_everett(model, segments, interp="spline"):
    """`model` (a crisp or ramp relay grid) with the weights of `everett_weights`; returns ``(model, info)`` like `fit_preisach`."""
    if model.linear:
        raise ValueError("Everett identification has no linear term: use a Preisach grid with linear=False")
    w, off = everett_weights(segments, np.asarray(model.levels), interp)
    fitted = model.with_linear_weights(jnp.asarray(np.concatenate([w, [off]])))
    A, y = design(fitted, segments)
    res = A @ np.asarray(fitted.linear_weights()) - y
    n_desc = sum(int(len(_as_seg(s)[0]) - np.argmax(_as_seg(s)[0])) for s in segments)
    return fitted, {
        "sse": float(res @ res),
        "n": int(A.shape[0]),
        "dof": float(min(n_desc, model.n_relays + 1)),
        "lam": None,
        "ridge": None,
        "method": f"everett-{interp}",
        "n_levels": model.n_levels,
        "width": float(model.width),
        "n_nonzero": int(np.sum(np.abs(w) > 0)),
        "n_negative": int(np.sum(w < 0)),
    }


#: Default inner-CV grids: levels per input range and penalty per sample.
N_LEVELS_GRID = (18, 24, 35)
LAM_GRID = (1e-5, 1e-4, 1e-3, 1e-2, 1e-1)


def _as_seg(seg):
    if hasattr(seg, "u"):  # a diagnosis Segment
        return seg.u, seg.y, seg.mask
    return seg[0], seg[1], (seg[2] if len(seg) > 2 else np.ones(len(seg[0]), bool))


def cv_fit_preisach(
    segments,
    u_min,
    u_max,
    *,
    n_levels_grid=N_LEVELS_GRID,
    lam_grid=LAM_GRID,
    ridge=0.0,
    linear=False,
    init="descended",
    ramp=True,
    everett=EVERETT_INTERPOLANTS,
    criterion="rmse",
    keep=None,
    verbose=False,
    progress=True,
):
    """Preisach fit with ``(n_levels, lam)`` chosen by inner cross-validation on ``segments`` only.

    Inner folds: leave one segment out, except the segments in ``keep`` (default:
    the one with the widest input range, e.g. the major loop, which always
    trains); with a single segment, its last 30 % (of the scored samples) is the
    inner validation block.  Criterion: pooled inner held-out RMSE.  The chosen
    setting is refitted on all segments.  When the segments are first-order
    reversal curves, the Everett (FORC-surface interpolation) grids of
    ``everett`` compete in the same inner folds (``lam`` is then None).
    ``criterion``: ``"rmse"`` (default, pooled inner RMSE) or ``"max"`` (pooled
    inner max |error|, the quantity of the error ratio e_r; noisier).
    Returns ``(model, info)``; ``info`` holds the CV table, the choice and the
    effective degrees of freedom.
    """
    if criterion not in ("rmse", "max"):
        raise ValueError(f"criterion must be 'rmse' or 'max', got {criterion!r}")
    key = "cv_rmse" if criterion == "rmse" else "cv_max_abs"

    segs = [_as_seg(s) for s in segments]
    if keep is None:
        keep = {int(np.argmax([np.ptp(np.asarray(u)) for u, _, _ in segs]))}
    if len(segs) - len(keep) >= 2:
        folds = [([j for j in range(len(segs)) if j != i], [i]) for i in range(len(segs)) if i not in keep]
        inner = "leave-one-segment-out (widest-range segment always trained)"
    else:  # time block inside one record: simulate from the start, score the block
        u, y, mask = segs[0]
        idx = np.flatnonzero(mask)
        cut = idx[int(round(0.7 * idx.size))]
        tr_mask, va_mask = mask & (np.arange(len(u)) < cut), mask & (np.arange(len(u)) >= cut)
        segs = [(u, y, tr_mask), (u, y, va_mask)] + segs[1:]
        folds = [([0] + list(range(2, len(segs))), [1])]
        inner = "time block: last 30 % of the training samples"
    table = []
    best = None
    # progress per grid size, weighted by its cost (the solves grow with the cube of the relay count)
    steps = Steps("Preisach cross-validation", len(n_levels_grid), unit="grid sizes", enabled=progress,
                  weights=[(n * (n + 1) / 2) ** 3 for n in n_levels_grid])  # fmt: skip
    for n in n_levels_grid:
        m0 = Preisach.from_range(u_min, u_max, n_levels=n, linear=linear, init=init, ramp=ramp)
        blocks = [design(m0, [s]) for s in segs]
        nonneg = m0.nonnegative_columns()
        P1 = penalty_matrix(m0, 1.0, ridge)
        for lam in lam_grid:
            sse, cnt, mx = 0.0, 0, 0.0
            for tr, va in folds:
                A = np.concatenate([blocks[i][0] for i in tr])
                y = np.concatenate([blocks[i][1] for i in tr])
                x, _ = solve_penalised(A, y, nonneg, P1 * (lam * A.shape[0]), 1.0, dof=False)
                for i in va:
                    r = blocks[i][0] @ x - blocks[i][1]
                    sse, cnt, mx = sse + float(r @ r), cnt + r.size, max(mx, float(np.max(np.abs(r), initial=0.0)))
            row = {
                "n_levels": int(n),
                "lam": float(lam),
                "method": "penalised",
                "cv_rmse": float(np.sqrt(sse / max(cnt, 1))),
                "cv_max_abs": mx,
            }
            table.append(row)
            say(f"  preisach inner CV: n_levels {n}, lam {lam:.0e}: rmse {row['cv_rmse']:.4g}, max {mx:.4g}", verbose)
            if best is None or row[key] < best[key]:
                best = row
        use_everett = everett and not linear and inner.startswith("leave-one") and forc_shaped(segs)
        for interp in everett if use_everett else ():
            sse, cnt, mx = 0.0, 0, 0.0
            for tr, va in folds:
                x = fit_everett(m0, [segs[i] for i in tr], interp)[0].linear_weights()
                for i in va:
                    r = blocks[i][0] @ np.asarray(x) - blocks[i][1]
                    sse, cnt, mx = sse + float(r @ r), cnt + r.size, max(mx, float(np.max(np.abs(r), initial=0.0)))
            row = {
                "n_levels": int(n),
                "lam": None,
                "method": f"everett-{interp}",
                "cv_rmse": float(np.sqrt(sse / max(cnt, 1))),
                "cv_max_abs": mx,
            }
            table.append(row)
            say(f"  preisach inner CV: n_levels {n}, everett-{interp}: rmse {row['cv_rmse']:.4g}, max {mx:.4g}", verbose)
            if row[key] < best[key]:
                best = row
        steps.advance(note=f"{n} levels")
    full = [_as_seg(s) for s in segments]
    m_best = Preisach.from_range(u_min, u_max, n_levels=best["n_levels"], linear=linear, init=init, ramp=ramp)
    if best["method"] == "penalised":
        model, info = fit_preisach(m_best, full, lam=best["lam"], ridge=ridge)
        info["method"] = "penalised"
    else:
        model, info = fit_everett(m_best, full, best["method"].split("-", 1)[1])
    info.update({"inner_cv": inner, "criterion": criterion, "n_inner_folds": len(folds), "cv_table": table, "chosen": best})
    return model, info
