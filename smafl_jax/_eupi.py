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
         + sum_m poly_m  s(k)^(m+2)                      # polynomial, m = 0.. (orders 2..Np)
         + offset                                        # p0

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
reached when the first input is approached from 0.

Grid rule (`EUPI.from_range`): ``n`` thresholds ``r_i = i / (2 n)``,
i = 1..n, i.e. from ``span/(2n)`` to half the input span (an operator of
threshold >= span/2 can no longer reverse inside the data range); tilts
geometrically spaced in [0.4, 2.5] (both sides of the symmetric tilt 1).
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from . import _config  # noqa: F401
from ._constraints import parameter, positive
from ._io import register_model
from ._operators import MODEL_METHODS, consistent_initial_state, play, play_weighted

__all__ = ["EUPI", "threshold_grid", "tilt_grid"]

_INITS = ("descended", "zero", "consistent")


def threshold_grid(n):
    """Documented threshold rule on the normalised input: ``r_i = i / (2 n)``, i = 1..n."""
    if int(n) < 0:
        raise ValueError(f"number of thresholds must be >= 0, got {n}")
    return np.arange(1, int(n) + 1, dtype=np.float64) / (2.0 * max(int(n), 1))


def tilt_grid(n, lo=0.4, hi=2.5):
    """Tilts geometrically spaced in ``[lo, hi]``."""
    if int(n) < 0:
        raise ValueError(f"number of tilts must be >= 0, got {n}")
    if int(n) == 1:
        return np.array([np.sqrt(lo * hi)])
    return np.geomspace(lo, hi, int(n))


@register_model
class EUPI(eqx.Module):
    """EUPI hysteresis model (eq. 2) as a PyTree; call `simulate(u)` for the output."""

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
    init: str = eqx.field(static=True, default="descended")
    # evaluation form of the operator bank: "scan" (sequential), "assoc" / "chunked" / "segmented" (exact
    # parallel-in-time forms of smafl_jax.ops, equal to scan bit for bit) or "auto" (choose_model_method)
    method: str = eqx.field(static=True, default="scan")
    # +1: output rises with the operator sum (displacement sensor); -1: falls (length sensor, sensor
    # mounted the other way). The operator gains stay >= 0 either way, so the sign lives here.
    orientation: int = eqx.field(static=True, default=1)

    def __check_init__(self):
        if self.orientation not in (1, -1):
            raise ValueError(f"EUPI orientation must be +1 or -1, got {self.orientation!r}")
        if self.init not in _INITS:
            raise ValueError(f"EUPI init must be one of {_INITS}, got {self.init!r}")
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

    def normalise(self, u):
        return (jnp.asarray(u, dtype=jnp.float64) - self.u_ref) / self.u_span

    def _initial_state(self, s0, r, a):
        if self.init == "descended":
            y0 = a * (s0 + r)  # upper bound at the first input: state left by a descent to u(0)
        elif self.init == "consistent":
            y0 = consistent_initial_state(s0, r, a)
        else:
            y0 = None
        return y0

    def operators(self, u):
        """Operator outputs ``(T, n_sym + n_alpha * n_asym)`` on the normalised input."""
        s = self.normalise(u)
        r, a = self._bank()
        return play(s, r, a, y0=self._initial_state(s[0], r, a), method=self.method)

    def features(self, u):
        """Design matrix ``(T, p)``: columns ``[s, F_sym, F_asym (tilt-major), s^2.., 1]``."""
        s = self.normalise(u)
        ops = self.operators(u)
        n_poly = np.shape(self.poly)[0]
        # poly_order=1 (no polynomial terms) gives an empty block, not a failing empty stack
        powers = jnp.stack([s ** (m + 2) for m in range(n_poly)], axis=-1) if n_poly else jnp.zeros((s.shape[0], 0))
        powers = powers.reshape(s.shape[0], n_poly)
        signed = float(self.orientation) * jnp.concatenate([s[:, None], ops], axis=1)
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
        theta = jnp.asarray(theta, dtype=jnp.float64)
        nv, nw, npoly = np.shape(self.v)[0], np.size(self.w), np.shape(self.poly)[0]
        expected = 1 + nv + nw + npoly + 1
        if theta.shape != (expected,):
            raise ValueError(f"expected {expected} linear weights, got shape {theta.shape}")
        i = 0
        gain = theta[0]
        i = 1
        v = theta[i : i + nv]
        i += nv
        w = theta[i : i + nw].reshape(np.shape(self.w))
        i += nw
        poly = theta[i : i + npoly]
        offset = theta[i + npoly]
        return eqx.tree_at(lambda m: (m.gain, m.v, m.w, m.poly, m.offset), self, (gain, v, w, poly, offset))

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
        poly = sum((c * s ** (m + 2) for m, c in enumerate(self.poly)), jnp.zeros_like(s))
        return float(self.orientation) * (self.gain * s + ops) + poly + self.offset
