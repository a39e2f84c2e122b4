"""Bayesian uncertainty for the identified models: log-posterior, vectorised emcee, diagnostics.

The sampled vector is the ravelled PyTree ``(trainable model leaves, noise)``
in *unconstrained* coordinates (positive fields through softplus, see
`smafl_jax.constrain`), so the density includes `log_jacobian`.  Priors are
stated on the physical values, elementwise, and can be overridden from JSON.

Linear gains (``linear=``):

The trainable leaves come from `smafl_jax.default_trainable`, i.e. from the hysteresis
protocol (`smafl_jax.models._hysteresis`): a hysteresis model's grids and spans (EUPI thresholds,
Preisach levels) are never sampled; its weights are its `linear_fields`.

- ``"sample"``: every trainable leaf (thermal k1 and all hysteresis weights) is sampled.
  Exact for the model as written (gains >= 0 respected), but the dimension is
  ~30 for the default EUPI and the ensemble sampler mixes slowly.
- ``"marginalise"`` (recommended when the hysteresis has many weights): only the
  nonlinear parameters (k1, noise scale, grids if trained) are sampled; the
  gains get a Gaussian prior ``N(0, tau^2)`` and are integrated out in closed
  form (Gaussian noise only).  Exact for *unbounded* gains; the positivity of
  the play-operator gains is dropped, so use it when the data pin the gains
  down (the usual case: thousands of samples, tens of gains).  Gains for the
  predictive draws come from their exact conditional Gaussian.
- ``"profile"``: gains replaced by their ridge least-squares estimate at each
  nonlinear point.  Cheapest, but ignores the gains' uncertainty, so intervals
  on k1 come out too narrow when the gains are poorly determined.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import logging
import math
import os
import shutil
import signal
import sys
import threading
import time
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax.flatten_util import ravel_pytree
from jax.typing import ArrayLike

from .. import _config  # noqa: F401
from .._errors import UserInputError
from ..identify._fit import as_fit_data, default_trainable
from ..models._constraints import constrain, log_jacobian, positive, unconstrain
from ..models._hysteresis import column_weight_scales, hysteresis_of, linear_field_columns, record_model, thermal_of
from ..models._simulate import simulate
from . import _cholesky as _chol

__all__ = [
    "Prior",
    "Posterior",
    "SampleRun",
    "ChainTooShortWarning",
    "default_priors",
    "hysteresis_priors",
    "check_model_supported",
    "linear_modes",
    "resolve_walkers",
    "load_priors",
    "run_sampler",
    "load_run",
    "diagnostics",
    "summarize",
]

log = logging.getLogger(__name__)

NOISE_MODELS = ("gaussian", "student-t")
LINEAR_MODES = ("sample", "marginalise", "profile")
_DISTS = {
    "normal": ("loc", "scale"),
    "lognormal": ("loc", "scale"),
    "halfnormal": ("scale",),
    "uniform": ("low", "high"),
    "flat": (),
}
_LOG2PI = math.log(2.0 * math.pi)


class ChainTooShortWarning(UserWarning):
    """The chain is shorter than ~50 autocorrelation times: its error bars are not reliable."""


# -- priors -------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class Prior:
    """Elementwise prior on a physical parameter value.

    ``normal(loc, scale)``, ``lognormal(loc, scale)`` (of ``log x``, x > 0),
    ``halfnormal(scale)`` (x > 0), ``uniform(low, high)``, ``flat`` (improper).
    """

    dist: str
    loc: float = 0.0
    scale: float = 1.0
    low: float = -math.inf
    high: float = math.inf

    def __post_init__(self):
        if self.dist not in _DISTS:
            raise UserInputError(f"unknown prior distribution {self.dist!r}; choose one of {sorted(_DISTS)}")
        if "scale" in _DISTS[self.dist] and not (np.all(np.asarray(self.scale) > 0) and np.all(np.isfinite(self.scale))):
            raise UserInputError(f"{self.dist} prior needs a finite scale > 0, got {self.scale}")
        if self.dist == "uniform" and not np.all(np.asarray(self.low) < np.asarray(self.high)):
            raise UserInputError(f"uniform prior needs low < high, got [{self.low}, {self.high}]")

    def logpdf(self, x):
        """Summed log density of the elements of ``x`` (normalised, except ``flat``)."""
        x = jnp.asarray(x)
        d = self.dist
        if d == "flat":
            return jnp.asarray(0.0)
        if d == "normal":
            z = (x - self.loc) / self.scale
            return jnp.sum(-0.5 * z * z - jnp.log(self.scale) - 0.5 * _LOG2PI + 0.0 * x)
        if d == "lognormal":
            lx = jnp.log(x)
            z = (lx - self.loc) / self.scale
            return jnp.sum(-0.5 * z * z - jnp.log(self.scale) - 0.5 * _LOG2PI - lx)
        if d == "halfnormal":
            z = x / self.scale
            return jnp.sum(jnp.where(x >= 0, -0.5 * z * z - jnp.log(self.scale) + 0.5 * math.log(2.0 / math.pi), -jnp.inf))
        # uniform
        inside = (x >= self.low) & (x <= self.high)
        return jnp.sum(jnp.where(inside, -jnp.log(jnp.asarray(self.high) - self.low) + 0.0 * x, -jnp.inf))

    def to_dict(self):
        return {"dist": self.dist, **{k: _jsonable(getattr(self, k)) for k in _DISTS[self.dist]}}

    @classmethod
    def from_dict(cls, d, where="prior"):
        if not isinstance(d, dict) or "dist" not in d:
            raise UserInputError(
                f"{where}: expected an object with a 'dist' entry, e.g. {{'dist': 'lognormal', 'loc': -3, 'scale': 1}}"
            )
        dist = d["dist"]
        if dist not in _DISTS:
            raise UserInputError(f"{where}: unknown distribution {dist!r}; choose one of {sorted(_DISTS)}")
        extra = set(d) - {"dist", *_DISTS[dist]}
        if extra:
            raise UserInputError(f"{where}: {dist} takes {list(_DISTS[dist])}, not {sorted(extra)}")
        missing = [k for k in _DISTS[dist] if k not in d]
        if missing:
            raise UserInputError(f"{where}: {dist} prior needs {missing}")
        kw = {}
        for k in _DISTS[dist]:
            try:
                val = float(d[k])
            except (TypeError, ValueError):
                raise UserInputError(f"{where}.{k}: expected a number, got {d[k]!r}") from None
            kw[k] = val
        return cls(dist, **kw)


def _jsonable(x):
    return float(x) if np.ndim(x) == 0 else np.asarray(x).tolist()


def load_priors(path: str | os.PathLike) -> dict[str, Prior]:
    """``{parameter name: Prior}`` from a JSON file ``{"thermal.k1": {"dist": ..., ...}, ...}``."""
    from .._io import read_json_file

    path = Path(path)
    doc = read_json_file(path, "priors file")
    doc = doc.get("priors", doc)
    return {str(k): Prior.from_dict(v, where=f"{path}: {k}") for k, v in doc.items()}


def _data_scale(data):
    """(output range, max |input|) of the records; `UserInputError` when their squares overflow float64.

    The Gaussian / Student-t likelihoods sum squared residuals, so values whose
    squares are not finite (magnitudes beyond ~1e150) cannot be sampled: the
    units must be rescaled.
    """
    ys = np.concatenate([np.asarray(y, dtype=np.float64) for _, y, _ in data])
    us = np.concatenate([np.asarray(u, dtype=np.float64) for u, _, _ in data])
    with np.errstate(over="ignore", invalid="ignore"):
        for what, x in (("output", ys), ("input", us)):
            if not np.isfinite(np.sum(np.square(x))):
                raise UserInputError(
                    f"the {what} values (up to {float(np.max(np.abs(x))):.3g}) are too large: their squares overflow "
                    "float64; rescale the column to other units"
                )
        yr = float(np.ptp(ys)) or float(np.max(np.abs(ys))) or 1.0
    return yr, float(np.max(np.abs(us))) or 1.0


def default_priors(names: Sequence[str], data: Any, model: Any = None) -> dict[str, Prior]:
    """Weakly informative priors for the parameter leaves ``names``, scaled by the data.

    The hysteresis part of ``model`` states its own (`hysteresis_priors`): its linear weights that are >= 0
    (`nonnegative_columns`: EUPI gain, v, w; Preisach relay weights) half-normal with scale 2x the output range,
    the signed ones (polynomial, offset) normal(0, 10x range), each times the field's `weight_scales` (Preisach
    relays: 1 / sqrt(n)); its other trainable fields by its `nonlinear_priors` (EUPI thresholds and tilts:
    lognormal around their grid scale; fitted operator memory logits: normal(0, 4)).  The parts every model
    shares are matched by name: k1 lognormal around the paper's 0.05 1/s, sd 2 in log (time constants
    ~0.4 s..1000 s at 95 %), a slow thermal mode's rate and ratio lognormal too (below); k2 lognormal around the
    value that maps ``max U^2`` to the output range, sd 3 (on
    their last two name parts, so a thermal ``k1`` nested in an extended model, ``base.thermal.k1``, gets the k1
    prior); the Joule lag's ``offset`` as a signed weight; the noise scale half-normal with the output's range as
    scale.  Anything else (catalogue effect parameters) is flat.
    """
    yr, umax = _data_scale(data)
    table = {
        "thermal.k1": Prior("lognormal", math.log(0.05), 2.0),
        "k1": Prior("lognormal", math.log(0.05), 2.0),
        # in log space: yr / umax^2 can over- or underflow for extreme units
        "thermal.k2": Prior("lognormal", math.log(0.05) + math.log(yr) - 2.0 * math.log(umax), 3.0),
        "k2": Prior("lognormal", math.log(0.05) + math.log(yr) - 2.0 * math.log(umax), 3.0),
        # a slow thermal mode (`JouleThermal.slow_k1`, ``slow_ratio``): time constants ~20 s..5000 s and shares of the
        # heat ~0.5-95 % at 95 %, around the 120 s and 25 % a fit starts from
        "thermal.slow_k1": Prior("lognormal", math.log(1.0 / 120.0), 1.5),
        "thermal.slow_ratio": Prior("lognormal", math.log(1.0 / 3.0), 2.0),
        "offset": Prior("normal", 0.0, 10.0 * yr),  # `JouleLag.offset` (a hysteresis' own offset is claimed above)
        "noise.sigma": Prior("halfnormal", scale=yr),
    }
    own = hysteresis_priors(model, yr) if model is not None else {}
    out = {}
    for name in names:
        tail = ".".join(name.split(".")[-2:])
        if name in own:
            out[name] = own[name]
        elif name in table:
            out[name] = table[name]
        elif tail in table and tail != "offset":
            out[name] = table[tail]
        else:
            out[name] = Prior("flat")
    return out


def hysteresis_priors(model, y_range: float) -> dict[str, Prior]:
    """``{sampler leaf name: Prior}`` for the fields of ``model``'s hysteresis part, from its protocol (see `default_priors`).

    ``y_range``: the output range the weights' scales refer to.  Empty for a model without a hysteresis part.
    """
    h = hysteresis_of(model)
    if h is None:
        return {}
    nonneg = np.asarray(h.nonnegative_columns(), dtype=bool)
    columns = linear_field_columns(h)
    scales = h.weight_scales()
    by_field = {}
    for field in h.linear_fields():
        scale = float(scales.get(field, 1.0))
        if np.all(nonneg[columns[field]]):
            by_field[field] = Prior("halfnormal", scale=2.0 * y_range * scale)
        else:
            by_field[field] = Prior("normal", 0.0, 10.0 * y_range * scale)
    for field, (dist, loc, scale) in h.nonlinear_priors().items():
        by_field.setdefault(field, Prior(dist, loc, scale))
    where = _hysteresis_leaf_names(model, by_field)
    return {where[f]: p for f, p in by_field.items() if f in where}


def _hysteresis_leaf_names(model, fields) -> dict[str, str]:
    """``{field of model's hysteresis part: its leaf name}`` (``"hysteresis.w"``, ``"base.hysteresis.w"``, ``"w"``...),
    the names `Posterior` gives the sampled leaves; fields that are None (an EUPI without fitted memory) are left out."""
    h = hysteresis_of(model)
    marks = {f: object() for f in fields if getattr(h, f, None) is not None}
    if not marks:
        return {}
    # tag the fields, then read their paths in the model's tree
    tagged = eqx.tree_at(lambda m: [getattr(m.hysteresis, f) for f in marks], model, list(marks.values()))
    where = {id(leaf): jax.tree_util.keystr(path).lstrip(".") for path, leaf in jax.tree_util.tree_flatten_with_path(tagged)[0]}
    return {f: where[id(mark)] for f, mark in marks.items()}


# -- posterior ----------------------------------------------------------------


class _Noise(eqx.Module):
    """Observation noise scale (one for all records)."""

    sigma: jnp.ndarray = positive()


def _leaf_name(path):
    name = jax.tree_util.keystr(path)
    # params are (model_part, noise): strip the tuple index, prefix the noise leaf
    if name.startswith("[0]"):
        name = name[3:]
    elif name.startswith("[1]"):
        name = "noise" + name[3:]
    return name.lstrip(".")


def _element_names(name, shape):
    if shape == ():
        return [name]
    return [f"{name}[{','.join(map(str, idx))}]" for idx in np.ndindex(*shape)]


def _start_rule(init, u0=None, memory=None):
    """A new record's start as static settings: thermal rule ``init`` (``u0`` V when ``"given"``), memory rule or None."""
    return (str(init), None if u0 is None else float(u0), None if memory is None else str(memory))


def _ridge_lstsq(A, y, ridge):
    """``argmin |A w - y|^2 + |ridge * w|^2`` from the normal equations, by the pool-safe Cholesky of `_cholesky` (an
    SVD is a LAPACK call that can deadlock under vmap on the CPU).

    A floor of 1e-10 of the largest diagonal entry keeps the system positive definite in floating point when the
    ridge is tiny and operator columns duplicate each other (an SVD would return the minimum-norm solution there;
    the floor moves the fitted values by about that relative amount)."""
    M = A.T @ A
    M = M + jnp.diag(ridge**2 + 1e-10 * jnp.max(jnp.diag(M)))
    return _chol.cho_solve(_chol.cholesky(M), A.T @ y)


def _likelihood_mask(mask, data) -> np.ndarray | None:
    """``mask`` (one boolean array per record, or None) as one 1/0 float array over the concatenated records; None
    when every sample counts.  Why: samples a resampling interpolated across a logger's gaps are not measurements
    (`Record.measured`); the likelihood leaves them out while the model still runs through them."""
    if mask is None:
        return None
    if isinstance(mask, np.ndarray) and mask.ndim == 1 and len(data) == 1:
        mask = [mask]
    mask = list(mask)
    if len(mask) != len(data):
        raise UserInputError(f"got {len(mask)} masks for {len(data)} records")
    out = []
    for i, (m, (u, _, _)) in enumerate(zip(mask, data)):
        m = np.ones(u.shape[0], bool) if m is None else np.asarray(m)
        if m.shape != u.shape or m.dtype != bool:
            raise UserInputError(f"mask {i}: expected a boolean array of shape {u.shape}, got {m.dtype} {m.shape}")
        out.append(m)
    flat = np.concatenate(out)
    if flat.sum() < 3:
        raise UserInputError(f"the masks keep {int(flat.sum())} samples in the likelihood; need at least 3")
    return None if flat.all() else flat.astype(np.float64)


def check_model_supported(model, where="model"):
    """`UserInputError` for models the posterior cannot handle: anything without a ``simulate(u, dt)``.

    Every saved model qualifies: a hysteresis model (EUPI, Preisach), a cascade, the Joule lag and a
    diagnose `ExtendedModel` (its effect parameters are sampled with the rest).
    """
    if not callable(getattr(model, "simulate", None)):
        raise UserInputError(f"{where}: holds a {type(model).__name__}, which has no simulate(u, dt) to condition on data")


def linear_modes(model):
    """The ``linear=`` modes `Posterior` accepts for ``model``: all three when its output is linear in
    its hysteresis weights (see `smafl_jax.models._hysteresis`), else only ``"sample"``."""
    if hysteresis_of(model) is not None and getattr(model, "linear_in_weights", False):
        return LINEAR_MODES
    return ("sample",)


def resolve_walkers(ndim, n_walkers=None):
    """Number of emcee walkers: default ``max(32, 2 ndim + 2)``, rounded up to even; at least ``2 ndim``."""
    if n_walkers is None:
        n_walkers = max(32, 2 * ndim + 2)
    n_walkers = int(n_walkers) + int(n_walkers) % 2
    if n_walkers < 2 * ndim:
        raise UserInputError(f"need at least 2 x {ndim} = {2 * ndim} walkers for {ndim} parameters, got {n_walkers}")
    return n_walkers


class Posterior:
    """Log-posterior of a model's trainable parameters and the noise scale, in unconstrained coordinates.

    ``data``: anything `smafl_jax.as_fit_data` accepts.  ``noise``: ``"gaussian"`` or
    ``"student-t"`` (``nu`` degrees of freedom, fixed).  ``sigma``: starting noise scale
    (default: RMS residual of ``model``).  ``priors``: ``{name: Prior}`` overriding the
    defaults (names as in `names_leaf`).  ``linear``: see the module docstring.
    ``gain_scale``: prior sd of the marginalised/profiled gains (default 10x output range).
    ``prior_only=True`` drops the likelihood (prior checks, tests of the Jacobian).  ``new_record_start``: for a model
    that holds one start per record of ``data`` (a joint fit's `for_record`), the thermal start rule ``(init, u0)`` a
    record outside ``data`` starts by in `predict`, with an optional operator-memory rule ``(init, u0, memory)`` (the
    joint fit's shared rule, as ``smafl simulate`` uses it).  ``mask``: one boolean array per record (or None): the
    samples the likelihood counts (e.g. `Record.measured`, which leaves out what a resampling interpolated); every
    record is still simulated whole.
    """

    def __init__(
        self,
        model,
        data,
        dt=None,
        *,
        trainable=None,
        noise="gaussian",
        nu=4.0,
        sigma=None,
        priors=None,
        linear="sample",
        gain_scale=None,
        prior_only=False,
        new_record_start=None,
        mask=None,
    ):
        if noise not in NOISE_MODELS:
            raise UserInputError(f"noise model must be one of {NOISE_MODELS}, got {noise!r}")
        if linear not in LINEAR_MODES:
            raise UserInputError(f"linear must be one of {LINEAR_MODES}, got {linear!r}")
        if not (float(nu) > 0):
            raise UserInputError(f"Student-t degrees of freedom must be > 0, got {nu}")
        if gain_scale is not None and not (math.isfinite(float(gain_scale)) and float(gain_scale) > 0):
            raise UserInputError(f"gain_scale (prior sd of the gains) must be > 0, got {gain_scale}")
        check_model_supported(model)
        self.data = as_fit_data(data, dt, model=model)
        self.mask = _likelihood_mask(mask, self.data)
        self.noise, self.nu, self.linear, self.prior_only = noise, float(nu), linear, bool(prior_only)
        spec = default_trainable(model) if trainable is None else trainable
        if linear != "sample":
            if linear not in linear_modes(model):
                raise UserInputError(
                    f"linear={linear!r} needs a model whose output is linear in its hysteresis weights (an EUPI, a "
                    "Preisach, a cascade of either), got "
                    f"{type(model).__name__}{' with output-side effects' if hysteresis_of(model) is not None else ''}"
                )
            if linear == "marginalise" and noise != "gaussian":
                raise UserInputError(
                    "marginalising the gains is exact only for Gaussian noise; use noise='gaussian' or linear='profile'"
                )
            fields = hysteresis_of(model).linear_fields()
            spec = eqx.tree_at(lambda s: [getattr(s.hysteresis, f) for f in fields], spec, [False] * len(fields))
        yr, _ = _data_scale(self.data)
        self.gain_scale = float(10.0 * yr if gain_scale is None else gain_scale)
        self.model = model
        self.spec = spec
        if sigma is None:
            res = np.concatenate(
                [np.asarray(simulate(record_model(model, i), u, d)) - y for i, (u, y, d) in enumerate(self.data)]
            )
            res = res if self.mask is None else res[self.mask > 0]
            sigma = float(np.sqrt(np.mean(res**2))) if np.all(np.isfinite(res)) else 0.1 * yr
            sigma = max(sigma, 1e-6 * yr)
        raw = unconstrain(model)
        raw_train, static = eqx.partition(raw, spec)
        # floored zeros (e.g. NNLS gains) sit at softplus^-1(1e-10) ~ -23, far in the tail
        # of any prior; start them where the density has mass.
        raw_train = jax.tree_util.tree_map(lambda x: jnp.maximum(x, -7.0), raw_train)
        params = (raw_train, unconstrain(_Noise(jnp.asarray(float(sigma)))))
        self.theta0 = np.asarray(ravel_pytree(params)[0])
        leaves, treedef = jax.tree_util.tree_flatten_with_path(params)
        self.names_leaf = [_leaf_name(p) for p, _ in leaves]
        self.shapes_leaf = [tuple(np.shape(x)) for _, x in leaves]
        self.names = [n for name, s in zip(self.names_leaf, self.shapes_leaf) for n in _element_names(name, s)]
        self.ndim = len(self.names)
        user = dict(priors or {})
        unknown = sorted(set(user) - set(self.names_leaf))
        if unknown:
            raise UserInputError(f"priors given for unknown parameters {unknown}; sampled parameters are {self.names_leaf}")
        pri = default_priors(self.names_leaf, self.data, model)
        pri.update(user)
        self.priors = pri
        self._d = _Density(
            static=static,
            args=tuple((jnp.asarray(u), jnp.asarray(y), jnp.asarray(d)) for u, y, d in self.data),
            # prior sd of each marginalised / profiled weight: gain_scale x the hysteresis' relative scale of that column
            gain_scale=jnp.asarray(
                self.gain_scale * column_weight_scales(hysteresis_of(model)) if linear != "sample" else self.gain_scale
            ),
            treedef=jax.tree_util.tree_structure(params),
            shapes=tuple(self.shapes_leaf),
            priors=tuple(pri[n] for n in self.names_leaf),
            noise=noise,
            nu=float(nu),
            linear=linear,
            prior_only=bool(prior_only),
            new_start=None if new_record_start is None else _start_rule(*new_record_start),
            mask=None if self.mask is None else jnp.asarray(self.mask),
        )
        if linear != "sample" and not jax.tree_util.tree_leaves(raw_train):
            self._d = dataclasses.replace(self._d, design=_fixed_design(self._d, model))

    def unpack(self, theta):
        """``(physical model, sigma)`` at the unconstrained vector ``theta`` (gains as in the template when not sampled)."""
        return self._d.unpack(jnp.asarray(theta))

    def log_prob(self, theta):
        """Log-posterior (up to a constant) at one unconstrained vector; -inf where undefined."""
        return self._d.log_prob(theta)

    def _loglik(self, model, sigma):
        return self._d._loglik(model, sigma)

    def __call__(self, thetas):
        """Vectorised log-posterior ``(n_walkers, ndim) -> (n_walkers,)`` for emcee (``vectorize=True``)."""
        thetas = np.asarray(thetas, dtype=np.float64)
        if thetas.ndim != 2 or thetas.shape[1] != self.ndim:
            raise ValueError(f"expected thetas of shape (n, {self.ndim}), got {thetas.shape}")
        return np.asarray(_batch_log_prob(self._d, jnp.asarray(thetas)))

    def physical(self, thetas):
        """Physical (constrained) values ``(n, ndim)`` in the order of `names`."""
        return np.asarray(_batch_physical(self._d, jnp.asarray(thetas, dtype=jnp.float64)))

    def initial_ball(self, n_walkers, rng, scale=1e-3):
        """Walkers in a small ball around the starting point (the fit), all with finite density."""
        theta0 = np.asarray(self.theta0, dtype=np.float64)
        width = scale * np.maximum(np.abs(theta0), 1.0)
        pos = theta0 + width * rng.standard_normal((n_walkers, self.ndim))
        lp = self(pos)
        for _ in range(50):
            bad = ~np.isfinite(lp)
            if not bad.any():
                return pos
            pos[bad] = theta0 + 0.1 * width * rng.standard_normal((int(bad.sum()), self.ndim))
            lp = self(pos)
        raise UserInputError("the log-posterior is not finite around the starting model; check the fit and the priors")

    def started_model(self, record=None):
        """The starting model (the fit) as it starts record ``record`` of the data, or a new record (None)."""
        return self._d.started(self.model, record)

    def predict(self, thetas, u, dt, rng, record=None):
        """Posterior-predictive draws on input ``u``: ``(mean function (S, T), with noise (S, T))``.

        With marginalised gains each draw takes gains from their exact conditional
        Gaussian given the sampled nonlinear parameters; with profiled gains, their estimate.
        ``record``: ``u`` is record ``record`` of the data (its own start, `record_model`); None: a new record,
        started by ``new_record_start`` when the model holds one start per record.
        """
        if record is not None and not 0 <= int(record) < len(self.data):
            raise UserInputError(f"record must be in [0, {len(self.data)}) (the conditioned records), got {record}")
        thetas = jnp.asarray(thetas, dtype=jnp.float64)
        keys = jax.random.split(jax.random.PRNGKey(int(rng.integers(2**31))), thetas.shape[0])
        u, dt = jnp.asarray(u, dtype=jnp.float64), jnp.asarray(dt, dtype=jnp.float64)
        f, yrep = _batch_predict(self._d, thetas, keys, u, dt, None if record is None else int(record))
        return np.asarray(f), np.asarray(yrep)


class _Density(eqx.Module):
    """The log-density as a PyTree (data and fixed parameters are leaves, settings static),
    so the jitted functions below compile once per model structure and data shape, not per instance."""

    static: object
    args: tuple
    gain_scale: jnp.ndarray
    treedef: object = eqx.field(static=True)
    shapes: tuple = eqx.field(static=True)
    priors: tuple = eqx.field(static=True)
    noise: str = eqx.field(static=True)
    nu: float = eqx.field(static=True)
    linear: str = eqx.field(static=True)
    prior_only: bool = eqx.field(static=True)
    new_start: tuple | None = eqx.field(static=True, default=None)  # (init, u0, memory) of a record outside args
    design: tuple | None = None  # `_fixed_design`: when only the noise scale is sampled
    mask: jnp.ndarray | None = None  # 1/0 per sample of the concatenated records (None: every sample in the likelihood)

    def unravel(self, theta):
        parts, i = [], 0
        for shape in self.shapes:
            size = int(np.prod(shape, dtype=int))
            parts.append(theta[i : i + size].reshape(shape))
            i += size
        return jax.tree_util.tree_unflatten(self.treedef, parts)

    def unpack(self, theta):
        raw_train, raw_noise = self.unravel(theta)
        return constrain(eqx.combine(raw_train, self.static)), constrain(raw_noise).sigma

    def physical(self, theta):
        raw_train, raw_noise = self.unravel(theta)
        return ravel_pytree((constrain(raw_train), constrain(raw_noise)))[0]

    def _n(self, n_rows):
        """Samples in the likelihood: the mask's ones, else every row."""
        return n_rows if self.mask is None else jnp.sum(self.mask)

    def _loglik_resid(self, r, sigma):
        n = self._n(r.shape[0])
        w = 1.0 if self.mask is None else self.mask  # masked samples contribute nothing
        if self.noise == "gaussian":
            return -0.5 * jnp.sum(w * (r / sigma) ** 2) - n * jnp.log(sigma) - 0.5 * n * _LOG2PI
        nu = self.nu
        c = jax.scipy.special.gammaln(0.5 * (nu + 1)) - jax.scipy.special.gammaln(0.5 * nu) - 0.5 * math.log(nu * math.pi)
        return n * c - n * jnp.log(sigma) - 0.5 * (nu + 1) * jnp.sum(w * jnp.log1p((r / sigma) ** 2 / nu))

    def _design(self, model):
        A = jnp.concatenate([record_model(model, i).features(u, d) for i, (u, _, d) in enumerate(self.args)])
        y = jnp.concatenate([y for _, y, _ in self.args])
        if self.mask is not None:  # masked rows zeroed: as if deleted from the normal equations (n counted apart)
            A, y = A * self.mask[:, None], y * self.mask
        # column scaling (exact: prior sd scaled alike) keeps the normal equations well conditioned
        c = jnp.maximum(jnp.sqrt(jnp.sum(A * A, axis=0) / self._n(A.shape[0])), 1e-12)
        return A / c[None, :], y, c

    def _fixed_weights(self, sigma, key=None):
        """Scaled weights given ``sigma`` for a fixed design: the conditional mean (= the ridge estimate), plus a
        draw from the conditional Gaussian when ``key`` is given (the eigenbasis of `_fixed_design`)."""
        _, _, c, U, lam, g = self.design
        tau = self.gain_scale * c
        shrink = 1.0 / (lam / sigma**2 + 1.0)
        v = shrink * g / sigma**2
        if key is not None:
            v = v + jnp.sqrt(shrink) * jax.random.normal(key, v.shape)
        return tau * (U @ v)

    def _fixed_loglik(self, sigma):
        """`_loglik` for a fixed design in O(p) per point (no p x p factorisation per walker and step)."""
        A, y, _, _, lam, g = self.design
        if self.linear == "profile":
            return self._loglik_resid(A @ self._fixed_weights(sigma) - y, sigma)
        n = self._n(y.shape[0])
        shrink = 1.0 / (lam / sigma**2 + 1.0)
        quad = jnp.sum(y * y) / sigma**2 - jnp.sum(shrink * g * g) / sigma**4
        logdet_cov = n * jnp.log(sigma**2) + jnp.sum(jnp.log1p(lam / sigma**2))
        return -0.5 * (quad + logdet_cov + n * _LOG2PI)

    def _gain_system(self, model, sigma):
        """Normal equations of the gains' conditional Gaussian (scaled coordinates)."""
        A, y, c = self._design(model)
        tau = self.gain_scale * c
        M = A.T @ A / sigma**2 + jnp.diag(1.0 / tau**2)
        b = A.T @ y / sigma**2
        return A, y, c, tau, M, b

    def log_prob(self, theta):
        raw_train, raw_noise = self.unravel(theta)
        model = constrain(eqx.combine(raw_train, self.static))
        phys_leaves = jax.tree_util.tree_leaves((constrain(raw_train), constrain(raw_noise)))
        lp = log_jacobian(raw_train) + log_jacobian(raw_noise)
        for leaf, prior in zip(phys_leaves, self.priors):
            lp = lp + prior.logpdf(leaf)
        if not self.prior_only:
            lp = lp + self._loglik(model, constrain(raw_noise).sigma)
        return jnp.where(jnp.isfinite(lp), lp, -jnp.inf)

    def _loglik(self, model, sigma):
        if self.linear == "sample":
            r = jnp.concatenate([record_model(model, i).simulate(u, d) - y for i, (u, y, d) in enumerate(self.args)])
            return self._loglik_resid(r, sigma)
        if self.design is not None:
            return self._fixed_loglik(sigma)
        A, y, c, tau, M, b = self._gain_system(model, sigma)
        if self.linear == "profile":
            return self._loglik_resid(A @ _ridge_lstsq(A, y, sigma / tau) - y, sigma)
        # marginal likelihood of y ~ N(0, sigma^2 I + A diag(tau^2) A^T) via the p x p system
        n = self._n(y.shape[0])
        L = _chol.cholesky(M)  # not LAPACK: batched under vmap it deadlocked XLA's CPU pool (bayes/_cholesky.py)
        z = _chol.solve_lower(L, b)
        logdet_M = 2.0 * jnp.sum(jnp.log(jnp.diag(L)))
        quad = jnp.sum(y * y) / sigma**2 - jnp.sum(z * z)
        logdet_cov = n * jnp.log(sigma**2) + jnp.sum(jnp.log(tau**2)) + logdet_M
        return -0.5 * (quad + logdet_cov + n * _LOG2PI)

    def started(self, model, record):
        """``model`` as it starts record ``record`` of the data, or a new record (None: ``new_start``)."""
        if record is not None:
            return record_model(model, record)
        if self.new_start is None:
            return model
        init, u0, memory = self.new_start
        model = model.with_thermal_start(init, u0)
        return model if memory is None else model.with_hysteresis(model.hysteresis.with_init(memory))

    def predict(self, theta, key, u, dt, record=None):
        model, sigma = self.unpack(theta)  # the gains below are conditioned on all records, each from its own start
        k1, k2 = jax.random.split(key)
        if self.design is not None:
            c = self.design[2]
            mean = self._fixed_weights(sigma, None if self.linear == "profile" else k1)
            model = model.with_hysteresis(model.hysteresis.with_linear_weights(mean / c))
        elif self.linear != "sample":
            A, y, c, tau, M, b = self._gain_system(model, sigma)
            if self.linear == "profile":
                mean = _ridge_lstsq(A, y, sigma / tau)
            else:
                L = _chol.cholesky(M)  # see _loglik
                mean = _chol.cho_solve(L, b)
                z = jax.random.normal(k1, mean.shape)
                mean = mean + _chol.solve_lower_transpose(L, z)
            model = model.with_hysteresis(model.hysteresis.with_linear_weights(mean / c))
        f = self.started(model, record).simulate(u, dt)
        e = jax.random.normal(k2, f.shape) if self.noise == "gaussian" else jax.random.t(k2, self.nu, f.shape)
        return f, f + sigma * e


@eqx.filter_jit
def _design_jit(density, model):
    return density._design(model)


def _fixed_design(density, model):
    """``(A, y, c, U, lam, g)`` for a model whose weights' design does not depend on the sampled parameters
    (only the noise scale is sampled: a Preisach, a bare EUPI).  With the prior sds ``tau`` of the scaled
    weights, ``diag(tau) A'A diag(tau) = U diag(lam) U'`` (one eigendecomposition) and ``g = U' diag(tau) A'y``;
    the marginal likelihood, the conditional mean and its draws are then O(p) / O(p^2) per point instead
    of a p x p Cholesky factorisation (p = 301 for the default Preisach grid)."""
    A, y, c = (np.asarray(x) for x in _design_jit(density, model))
    tau = np.asarray(density.gain_scale) * c
    lam, U = np.linalg.eigh((A.T @ A) * np.outer(tau, tau))
    g = U.T @ (tau * (A.T @ y))
    return tuple(jnp.asarray(x) for x in (A, y, c, U, np.maximum(lam, 0.0), g))


#: Walkers x samples evaluated at once (one vmapped batch) by the log-density: a batch keeps each walker's design
#: (samples x columns) alive: `smafl sample` of an EUPI cascade on a 90 000-sample record (56 walkers) peaked at 10.3 GB
#: in one batch and at 1.6 GB in batches of 11, with the same chain (session 32).  Records up to 31 250 samples keep 32
#: walkers in one batch, as before.
WALKER_SAMPLES_PER_BATCH = 1_000_000


def walker_batch(n_walkers: int, n_samples: int) -> int:
    """Walkers per vmapped batch of the log-density (`WALKER_SAMPLES_PER_BATCH`; at least 1, at most all)."""
    return max(1, min(int(n_walkers), WALKER_SAMPLES_PER_BATCH // max(int(n_samples), 1)))


def _in_batches(fn, xs, batch):
    """``vmap(fn)(xs)`` over the leading axis, evaluated ``batch`` at a time in sequence (the memory of one batch).

    The last batch is padded with copies of the last element and cut off after, so every batch has one shape: one
    scan over equal batches.  Why not ``lax.map(..., batch_size=)``: its separate remainder batch hung XLA's CPU
    runtime for good (no thread busy, the result never ready) on the 200 predictive draws of a 7 500-sample record
    (batches of 133), in 3 of 3 runs, while the same draws as one vmap or in equal padded batches returned in 1-2 s.
    """
    n = jax.tree_util.tree_leaves(xs)[0].shape[0]
    if batch >= n:
        return jax.vmap(fn)(xs)
    k = -(-n // batch)

    def split(x):
        x = jnp.concatenate([x, jnp.repeat(x[-1:], k * batch - n, axis=0)]) if k * batch > n else x
        return x.reshape(k, batch, *x.shape[1:])

    out = jax.lax.map(jax.vmap(fn), jax.tree_util.tree_map(split, xs))
    return jax.tree_util.tree_map(lambda y: y.reshape(k * batch, *y.shape[2:])[:n], out)


def _vmapped_log_prob(density, thetas):
    n = sum(int(u.shape[0]) for u, _, _ in density.args)  # static under jit: shapes
    return _in_batches(density.log_prob, thetas, walker_batch(thetas.shape[0], n))


# The hot function of sampling (emcee calls it once per step): one trace per density structure and shapes;
# tests check with `eqx.debug.get_num_traces` that new values never retrace.
_log_prob_traced = eqx.debug.assert_max_traces(_vmapped_log_prob, max_traces=None)


@jax.jit
def _batch_log_prob(density, thetas):
    return _log_prob_traced(density, thetas)


@jax.jit
def _batch_physical(density, thetas):
    return jax.vmap(density.physical)(thetas)


@functools.partial(jax.jit, static_argnames=("record",))
def _batch_predict(density, thetas, keys, u, dt, record=None):
    batch = walker_batch(thetas.shape[0], u.shape[0])
    return _in_batches(lambda tk: density.predict(tk[0], tk[1], u, dt, record), (thetas, keys), batch)


# -- running ------------------------------------------------------------------


@dataclasses.dataclass
class SampleRun:
    """A finished (or resumed) chain: ``chain`` (n_steps, n_walkers, ndim) in unconstrained coordinates."""

    chain: np.ndarray
    log_prob: np.ndarray
    acceptance_fraction: np.ndarray
    names: list
    path: str | None
    resumed_from: int


def _hdf_backend(path, name, read_only=False):
    """emcee's HDF5 backend, made tolerant of a reader holding the file for a moment.

    HDF5 locks the file while it is open; emcee opens it for every step, so a
    concurrent reader (a user inspecting the chain) would make the sampler crash
    with ``BlockingIOError``.  Opening is retried for up to 30 s instead.
    """
    import emcee

    class _Backend(emcee.backends.HDFBackend):
        def open(self, mode="r"):
            deadline = time.monotonic() + 30.0
            while True:
                try:
                    return super().open(mode)
                except BlockingIOError:
                    if time.monotonic() > deadline:
                        raise
                    time.sleep(0.05)

        def save_step(self, state, accepted):
            with _interrupt_deferred():  # a Ctrl-C in the middle of the HDF5 write would leave the file unreadable
                super().save_step(state, accepted)

    return _Backend(str(path), name=name, read_only=read_only)


@contextlib.contextmanager
def _interrupt_deferred():
    """Hold a Ctrl-C (SIGINT) or a SIGTERM until the block has run, then act on it: for short writes that must not be
    cut in two.

    Only in the main thread, and only signals with a Python handler (Python's SIGINT handler, the CLI's SIGTERM
    handler): elsewhere nothing changes."""
    main = threading.current_thread() is threading.main_thread()
    held = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)} if main else {}
    held = {s: h for s, h in held.items() if callable(h)}  # SIG_DFL / SIG_IGN are not Python handlers
    if not held:
        yield
        return
    pending = []
    for s in held:
        signal.signal(s, lambda *args: pending.append(args))
    try:
        yield
    finally:
        for s, h in held.items():
            signal.signal(s, h)
    if pending:
        held[pending[0][0]](*pending[0])  # the handler raises (KeyboardInterrupt) as it would have in the block


def _backend_ok(path, name):
    """Iteration count of a readable emcee HDF5 chain, or None if unreadable."""
    try:
        be = _hdf_backend(path, name, read_only=True)
        it = int(be.iteration)
        if it > 0:
            be.get_last_sample()
        return it
    except (OSError, KeyError, ValueError, AttributeError, RuntimeError):
        return None


def _checkpoint(path):
    """Atomic copy of the (closed) HDF5 file: the fallback if a kill corrupts the live file."""
    bak = Path(str(path) + ".bak")
    tmp = bak.with_name(bak.name + ".tmp")
    with _interrupt_deferred():  # a Ctrl-C would leave the temporary copy behind
        shutil.copyfile(path, tmp)
        with open(tmp, "rb") as f:
            os.fsync(f.fileno())
        os.replace(tmp, bak)


def run_sampler(
    posterior: Posterior,
    n_steps: int,
    *,
    n_walkers: int | None = None,
    path: str | os.PathLike | None = None,
    name: str = "mcmc",
    seed: int = 0,
    resume: bool = True,
    progress: bool = True,
    checkpoint_s: float = 10.0,
    initial: ArrayLike | None = None,
    on_step: Callable[..., Any] | None = None,
) -> SampleRun:
    """Run (or resume) `emcee.EnsembleSampler` with the vectorised log-posterior.

    With ``path`` the chain goes to an emcee HDF5 backend.  If the file already
    holds a chain and ``resume`` is true, sampling continues from its last step
    until the chain has exactly ``n_steps`` steps (emcee stores the random state,
    so a resumed run continues the same Markov chain).  A copy taken between
    steps every ``checkpoint_s`` seconds is used when a hard kill has left the
    live file unreadable (the steps since the copy are recomputed, never duplicated).
    ``on_step(k)``: called with the number of steps the chain holds, once before sampling (the steps already there)
    and after each new step once it is saved.  A Ctrl-C raises KeyboardInterrupt from here with every completed step
    saved (none cut in two), and without emcee's dump of the walkers' positions.
    """
    import emcee

    n_steps = int(n_steps)
    if n_steps < 1:
        raise UserInputError(f"number of steps must be >= 1, got {n_steps}")
    ndim = posterior.ndim
    n_walkers = resolve_walkers(ndim, n_walkers)
    rng = np.random.default_rng(seed)
    backend = None
    done = 0
    if path is not None:
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        if path.exists() and resume:
            it = _backend_ok(path, name)
            bak = Path(str(path) + ".bak")
            if it is None:
                it_bak = _backend_ok(bak, name) if bak.exists() else None
                if it_bak is None:
                    raise UserInputError(
                        f"{path}: the chain file is unreadable and has no usable checkpoint; rerun with a fresh output (restart)"
                    )
                log.warning(
                    f"note: {path} was left unreadable by an interruption; continuing from its checkpoint at step {it_bak}"
                )
                shutil.copyfile(bak, path)
                it = it_bak
            done = it
        elif path.exists():
            path.unlink()
        backend = _hdf_backend(path, name)
        if done and backend.shape != (n_walkers, ndim):
            raise UserInputError(
                f"{path}: holds a chain of shape {backend.shape} (walkers, parameters); this run has {(n_walkers, ndim)}; restart instead of resuming"
            )
        if done > n_steps:
            raise UserInputError(f"{path}: already holds {done} steps, more than the {n_steps} requested")
        if not done:
            backend.reset(n_walkers, ndim)
    sampler = emcee.EnsembleSampler(n_walkers, ndim, posterior, vectorize=True, backend=backend)
    # emcee wraps the density in a function that prints the walkers' positions and a traceback for ANY exception
    # raised inside it (a Ctrl-C lands there nearly always: the density is where the time goes) before re-raising
    # it; the vectorised density needs no wrapper (no args / kwargs), so it is called directly
    sampler.log_prob_fn = posterior
    start = None
    if done:
        state = None  # emcee restores the last position, log-probabilities and random state
        log.warning(f"resuming {path} at step {done} of {n_steps}")  # a note the user must see: the chain is extended
    else:
        sampler.random_state = np.random.RandomState(int(rng.integers(2**31))).get_state()
        state = posterior.initial_ball(n_walkers, rng) if initial is None else np.asarray(initial)
        start = np.array(state, dtype=np.float64)
        if path is not None:
            _store_start(backend, start)
    remaining = n_steps - done
    if on_step is not None:
        on_step(done)
    if remaining > 0:
        if state is None:
            state = sampler.get_last_sample()
        last = time.monotonic()
        # a bar redrawn 25 times a second is one endless line in a log file (a batch job's stderr): off a terminal,
        # at most one update every 30 s
        bar = {"desc": "sampling", "file": sys.stderr, **({} if sys.stderr.isatty() else {"mininterval": 30.0})}
        kwargs = {"progress": progress, "progress_kwargs": bar} if progress else {}
        for i, _ in enumerate(sampler.sample(state, iterations=remaining, **kwargs)):
            # here the step is saved and the file closed: safe to copy
            if path is not None and (time.monotonic() - last >= checkpoint_s):
                _checkpoint(path)
                last = time.monotonic()
            if on_step is not None:
                on_step(done + i + 1)
        if path is not None:
            _checkpoint(path)
    return _collect(sampler.backend, posterior.names, str(path) if path is not None else None, done, start)


_START = "start_coords"  # dataset beside emcee's in the HDF5 group: the walkers' starting positions


def _store_start(backend, start):
    with backend.open("a") as f:
        g = f[backend.name]
        if _START in g:
            del g[_START]
        g.create_dataset(_START, data=start)


def _read_start(backend):
    try:
        with backend.open() as f:
            g = f[backend.name]
            return np.asarray(g[_START]) if _START in g else None
    except (OSError, KeyError, AttributeError):
        return None


def _acceptance_from_chain(chain, start):
    """Per-walker fraction of steps that moved: a stretch move is accepted iff the position changes.

    Counted from the stored chain rather than emcee's running ``accepted`` total,
    which a hard kill between emcee's writes can leave one step ahead of the
    chain (so a resumed run would count that step twice).  Without the stored
    start (files written by older versions) the first step is not counted.
    """
    if start is not None and start.shape == chain.shape[1:]:
        chain = np.concatenate([start[None], chain], axis=0)
    if chain.shape[0] < 2:
        return np.zeros(chain.shape[1])
    moved = np.any(chain[1:] != chain[:-1], axis=-1)
    return moved.mean(axis=0)


def _collect(backend, names, path, resumed_from, start=None):
    chain = np.asarray(backend.get_chain())
    if start is None and path is not None:
        start = _read_start(backend)
    return SampleRun(
        chain=chain,
        log_prob=np.asarray(backend.get_log_prob()),
        acceptance_fraction=_acceptance_from_chain(chain, start),
        names=list(names),
        path=path,
        resumed_from=resumed_from,
    )


def load_run(path: str | os.PathLike, names: Sequence[str], name: str = "mcmc") -> SampleRun:
    """`SampleRun` from an emcee HDF5 file written by `run_sampler`."""
    return _collect(_hdf_backend(path, name, read_only=True), names, str(path), 0)


# -- diagnostics and summary --------------------------------------------------


def _or_length(tau, n):
    return np.where(np.isfinite(tau), tau, float(n))


def diagnostics(run: SampleRun, burn: int | None = None, *, warn: bool = True) -> dict[str, Any]:
    """emcee autocorrelation times, acceptance fraction and effective sample sizes.

    ``burn=None`` discards ``max(n_steps // 5, 3 tau_max)`` (at most half the chain).
    Warns (`ChainTooShortWarning`) when the kept chain is shorter than 50 tau_max,
    emcee's own criterion for a reliable tau.
    """
    import emcee

    chain = run.chain
    n_steps, n_walkers, _ = chain.shape
    with np.errstate(invalid="ignore", divide="ignore"):
        # a parameter on which some walker never moved has no autocorrelation estimate (0/0): count it as the whole chain
        tau_all = _or_length(emcee.autocorr.integrated_time(chain, tol=0), n_steps)
    if burn is None:
        burn = min(n_steps // 2, max(n_steps // 5, int(math.ceil(3 * np.nanmax(tau_all)))))
    burn = int(burn)
    if not 0 <= burn < n_steps:
        raise UserInputError(f"burn-in must be in [0, {n_steps}), got {burn}")
    kept = chain[burn:]
    n_kept = kept.shape[0]
    with np.errstate(invalid="ignore", divide="ignore"):
        tau = _or_length(emcee.autocorr.integrated_time(kept, tol=0), n_kept)
    ess = n_kept * n_walkers / tau
    tau_max = float(np.nanmax(tau))
    reliable = bool(n_kept >= 50 * tau_max)
    messages = []
    if not reliable:
        msg = (
            f"chain too short for reliable estimates: {n_kept} steps kept after burn-in, fewer than 50 x the "
            f"largest autocorrelation time ({tau_max:.1f} steps); run at least {int(math.ceil(50 * tau_max + burn))} steps"
        )
        messages.append(msg)
        if warn:
            warnings.warn(msg, ChainTooShortWarning, stacklevel=2)
    acc = float(np.mean(run.acceptance_fraction))
    if not 0.1 <= acc <= 0.8:
        messages.append(f"mean acceptance fraction {acc:.2f} is outside [0.1, 0.8]: the ensemble may be stuck or badly scaled")
    return {
        "burn": burn,
        "n_steps": int(n_steps),
        "n_walkers": int(n_walkers),
        "autocorr_time": tau,
        "ess": ess,
        "acceptance_fraction": acc,
        "reliable": reliable,
        "warnings": messages,
    }


def _stats(x):
    q = np.quantile(x, [0.025, 0.05, 0.5, 0.95, 0.975])
    return {
        "mean": float(np.mean(x)),
        "sd": float(np.std(x, ddof=1)),
        "q025": float(q[0]),
        "q05": float(q[1]),
        "median": float(q[2]),
        "q95": float(q[3]),
        "q975": float(q[4]),
    }


def derived_quantities(posterior, phys):
    """Thermal time constant ``1/k1`` and steady-state gain ``k2/k1`` (when k2 is identified)."""
    names = posterior.names
    out = {}
    k1n = next((n for n in names if n in ("thermal.k1", "k1") or n.endswith(".thermal.k1")), None)
    k2n = next((n for n in names if n in ("thermal.k2", "k2") or n.endswith(".thermal.k2")), None)
    if k1n:
        out["time_constant_s"] = _stats(1.0 / phys[:, names.index(k1n)])
    if k1n and k2n:
        out["steady_state_gain"] = _stats(phys[:, names.index(k2n)] / phys[:, names.index(k1n)])
    elif thermal_of(posterior.model) is not None:
        out["steady_state_gain"] = {
            "identified": False,
            "note": "k2 does not affect the cascade's displacement (it cancels in "
            "sqrt(theta k1/k2)); K2/K1 is identified only by the JouleThermal model fitted alone (U^2 -> output)",
        }
    elif k1n and (k2 := _model_leaf(posterior.model, k1n[: -len("k1")] + "k2")) is not None:
        # k1 sampled, the same thermal stage's k2 held fixed (a Joule model fitted with k2 given): say at what value
        out["steady_state_gain"] = {"identified": False, "note": f"k2 held fixed at {float(k2):g}"}
    return out


def _model_leaf(model, name):
    """The leaf of ``model`` that the sampler would name ``name`` (`_leaf_name`), or None."""
    for path, leaf in jax.tree_util.tree_flatten_with_path(model)[0]:
        if jax.tree_util.keystr(path).lstrip(".") == name:
            return leaf
    return None


def summarize(posterior: Posterior, run: SampleRun, burn: int | None = None, *, warn: bool = True) -> dict[str, Any]:
    """``summary.json`` content: per-parameter posterior statistics (physical units) and run diagnostics."""
    diag = diagnostics(run, burn, warn=warn)
    flat = run.chain[diag["burn"] :].reshape(-1, posterior.ndim)
    phys = posterior.physical(flat)
    params = {}
    for j, name in enumerate(posterior.names):
        params[name] = {**_stats(phys[:, j]), "autocorr_time": float(diag["autocorr_time"][j]), "ess": float(diag["ess"][j])}
    return {
        "parameters": params,
        "derived": derived_quantities(posterior, phys),
        "autocorr_time": {n: float(t) for n, t in zip(posterior.names, diag["autocorr_time"])},
        "autocorr_time_max": float(np.nanmax(diag["autocorr_time"])),
        "acceptance_fraction": diag["acceptance_fraction"],
        "n_steps": diag["n_steps"],
        "n_walkers": diag["n_walkers"],
        "burn": diag["burn"],
        "n_samples": int(flat.shape[0]),
        "ess_min": float(np.nanmin(diag["ess"])),
        "reliable": diag["reliable"],
        "warnings": diag["warnings"],
        "settings": {
            "noise": posterior.noise,
            "nu": posterior.nu if posterior.noise == "student-t" else None,
            "linear": posterior.linear,
            "gain_scale": posterior.gain_scale if posterior.linear != "sample" else None,
            "priors": {k: v.to_dict() for k, v in posterior.priors.items()},
        },
    }
