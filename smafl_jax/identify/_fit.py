"""Identification: profiled (variable-projection) initialiser + joint gradient-based refinement.

Two stages:

1. Initialiser.  For fixed thermal parameters, thresholds and tilts the EUPI
   is linear in its gains, so the paper's constrained least squares (play
   gains >= 0, polynomial and offset free) is solved exactly by bounded-variable
   least squares (`init_linear`, scipy ``lsq_linear(method="bvls")``).  When the
   model also has a thermal time constant to identify (`Cascade`, `JouleLag`),
   the gains are *profiled out*: the loss at the best gains is a function of
   ``k1`` alone.  It is evaluated on a log-spaced grid of ``k1`` candidates
   (the multi-start; the features of all candidates come from one `vmap` over
   the thermal scan) and the best candidate is refined by a bounded 1-D search
   (Brent) on ``log k1``.  For the default trainable set (``k1`` + gains) this
   *is* the joint least-squares optimum, with the sign constraints exact.
2. Joint refinement of every trainable leaf (thresholds and tilts optionally)
   through the scan, by optimistix (Levenberg-Marquardt, Gauss-Newton, BFGS;
   positivity by softplus reparametrisation inside the residual function) or
   jaxopt (L-BFGS-B with bounds, projected gradient; positivity by bounds in
   physical coordinates).  Default: ``"lm"``.

Failure story: a non-finite model output at the start raises `UserInputError`
naming the record and sample; a refinement that produces NaN/inf, or ends worse
than its start, is discarded (the initialiser's model is kept) and
``FitResult.message`` says so; one that does not lower the loss is said in
``message`` and ``info`` and logged.  Bad data (shapes, non-finite values, a
missing sample time for plain arrays) raise `UserInputError` in `as_fit_data`.  Nothing is random: equal inputs give bitwise
equal results.
"""

from __future__ import annotations

import dataclasses
import logging
import time
from collections.abc import Iterable, Sequence
from typing import Any, NamedTuple, TypeVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
from jax.typing import ArrayLike

from .. import _config  # noqa: F401
from .._blas import blas_limited
from .._compile_cache import persistent_cache_dir, release_if_needed
from .._errors import UserInputError
from .._progress import count_step, heartbeat, say, shown
from ..models._constraints import POSITIVE_FLOOR, constrain, positive_mask, unconstrain
from ..models._hysteresis import hysteresis_of, record_model, thermal_of
from ..models._padding import pad_records
from ..models._simulate import (
    UNUSED_DT,
    check_sample_time,
    compile_form,
    compile_form_spec,
    first_bad,
    user_form,
    uses_sample_time,
)
from . import varpro
from ._gain_prior import check_gain_prior, map_gains
from ._metrics import NOISE_FLOOR_WARN, noise_floor
from ._stall import STALL_MIN_GAIN, STALL_WINDOW, StallStop
from ._varpro_refine import refine_projected
from .varpro import FIT_SOLVE

__all__ = ["FitResult", "fit", "fit_many", "init_linear", "init_profile", "default_trainable", "as_fit_data", "SOLVERS"]

logger = logging.getLogger(__name__)

#: Fewest samples a record to fit may have.
MIN_FIT_SAMPLES = 3

#: A model type: the initialisers return a model of the class they were given.
_Model = TypeVar("_Model", bound=eqx.Module)


class FitResult(NamedTuple):
    """Outcome of `fit`: the physical model and how the solver got there."""

    model: Any
    loss: float  # 0.5 * sum of (weighted) squared residuals over all records
    n_steps: int
    converged: bool
    message: str
    solver: str
    init_loss: float = float("nan")  # loss after the initialiser, before the joint refinement
    info: dict | None = None  # stage details: profile grid, timings


def _is_pair(data: Any, record_type: type) -> bool:
    """One ``(u, y)`` pair or ``(u, y, dt)`` triple (its first entry an array), not a sequence of records."""
    return (
        isinstance(data, tuple)
        and len(data) in (2, 3)
        and not isinstance(data[0], (tuple, list, record_type))
        and np.ndim(data[0]) >= 1
    )


def _as_array(x: Any, what: str) -> np.ndarray:
    try:
        return np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError):
        raise UserInputError(f"{what}: expected an array of numbers, got {type(x).__name__}") from None


def as_fit_data(
    data: Any, dt: float | None = None, *, model: Any = None, names: Sequence[str] | None = None
) -> tuple[tuple[np.ndarray, np.ndarray, float], ...]:
    """Normalise fit data to a tuple of ``(u, y, dt)`` float64 numpy triples.

    Accepts a `Record`, a sequence of `Record`, a ``(u, y)`` pair with ``dt``, one ``(u, y, dt)`` triple
    or a sequence of them.  Plain arrays carry no time, so they need ``dt`` (the sample time in seconds), unless
    ``model`` is given and its output does not depend on time (a hysteresis model on its own,
    `smafl_jax.models._simulate.uses_sample_time`).  Bad shapes, non-finite values and a missing or non-positive
    ``dt`` raise `UserInputError` naming the record, the array and the first bad index.  ``names``: one name per
    record, used in those messages (``fit data 'run_03' (0): ...`` instead of ``fit data 0: ...``).
    """
    items = _fit_items(data, "fit data")
    if names is not None:
        names = [str(n) for n in names]
        if len(names) != len(items):
            raise UserInputError(f"fit data: got {len(names)} names for {len(items)} records")
    labels = [_fit_label(i, None if names is None else names[i]) for i in range(len(items))]
    return _normalised(items, dt, model, labels)


def _fit_label(i: int, name: str | None = None) -> str:
    """How an error message names fit record ``i``: ``fit data 'run_03' (3)`` when it has a name, else ``fit data 3``."""
    return f"fit data {name!r} ({i})" if name else f"fit data {i}"


def _fit_items(data: Any, label: str) -> list:
    """The records of fit data as a list (one `Record` or ``(u, y[, dt])`` tuple each), not yet checked."""
    from ..data._data import Record

    if isinstance(data, Record):
        return [data]
    if _is_pair(data, Record):
        return [data]  # one (u, y) pair or (u, y, dt) triple, not a sequence of two or three records
    if isinstance(data, np.ndarray) or not isinstance(data, Iterable):
        shape = f" of shape {np.shape(data)}" if isinstance(data, np.ndarray) else ""
        raise UserInputError(
            f"{label}: expected a Record, a (u, y) tuple, a (u, y, dt) tuple or a list of them, got {type(data).__name__}{shape}"
        )
    return list(data)


def _normalised(items: list, dt: float | None, model: Any, labels: Sequence[str]) -> tuple:
    """`as_fit_data` of `_fit_items`, each record's errors starting with its entry of ``labels``."""
    from ..data._data import Record

    needs_dt = model is None or uses_sample_time(model)
    out = []
    for item, label in zip(items, labels, strict=True):
        if isinstance(item, Record):
            if item.y is None:
                raise UserInputError(f"{label}: the record ({item.name}) has no output column to fit")
            u, y, d = item.u, item.y, item.dt
        elif isinstance(item, (tuple, list)) and len(item) in (2, 3):
            u, y, d = item if len(item) == 3 else (*item, None)
            if d is None:
                d = dt
        else:
            shape = f" of shape {np.shape(item)}" if isinstance(item, np.ndarray) else ""
            raise UserInputError(
                f"{label}: expected a Record or a (u, y) / (u, y, dt) tuple, got {type(item).__name__}{shape}"
                + ("; pass one record as a tuple (u, y), not a list [u, y]" if np.ndim(item) == 1 else "")
            )
        u = _as_array(u, f"{label}: input u")
        y = _as_array(y, f"{label}: output y")
        for name, x in (("input u", u), ("output y", y)):
            if x.ndim != 1:
                raise UserInputError(
                    f"{label}: the {name} must be 1-D (one sample per time step), got shape {x.shape}"
                    + (f"; one column (N, 1): pass {name[-1]}[:, 0]" if x.ndim == 2 and x.shape[1] == 1 else "")
                )
        if u.shape != y.shape:
            raise UserInputError(f"{label}: the input u has {u.shape[0]} samples but the output y has {y.shape[0]}")
        if u.shape[0] < MIN_FIT_SAMPLES:
            raise UserInputError(f"{label}: need at least {MIN_FIT_SAMPLES} samples, got {u.shape[0]}")
        for name, x in (("input u", u), ("output y", y)):
            bad = first_bad(x)
            if bad is not None:
                raise UserInputError(
                    f"{label}: the {name} is not finite at index {bad[0][0]} (value {bad[1]}); remove or fill it first"
                )
        if d is None:
            if needs_dt:
                kind = f"a {type(model).__name__}'s output depends on time" if model is not None else "the model needs it"
                raise UserInputError(
                    f"{label}: dt (the sample time in seconds) is required: plain (u, y) arrays carry no time and "
                    f"{kind}; pass it, e.g. sj.fit(model, (u, y), 0.05), or a Record (sj.load_record), which carries "
                    "its own"
                )
            d = UNUSED_DT
        check_sample_time(d, f"{label}: dt")
        out.append((u, y, float(d)))
    if not out:
        raise UserInputError("no data to fit")
    return tuple(out)


def _as_weights(weights, data):
    """Per-record 0/1 (or any >= 0) sample weights; None -> all ones."""
    if weights is None:
        return tuple(np.ones(u.shape[0]) for u, _, _ in data)
    if isinstance(weights, np.ndarray) and len(data) == 1 and weights.ndim == 1:
        weights = [weights]
    weights = list(weights)
    if len(weights) != len(data):
        raise UserInputError(f"got {len(weights)} weight arrays for {len(data)} records")
    out = []
    for i, (w, (u, _, _)) in enumerate(zip(weights, data)):
        w = np.ones(u.shape[0]) if w is None else np.asarray(w, dtype=np.float64)
        if w.shape != u.shape:
            raise UserInputError(f"weights {i}: shape {w.shape} does not match the record's {u.shape}")
        if not np.all(np.isfinite(w)) or np.any(w < 0):
            raise UserInputError(f"weights {i}: must be finite and >= 0")
        out.append(w)
    if sum(float(np.sum(w > 0)) for w in out) < 3:
        raise UserInputError("fewer than 3 samples carry weight; nothing to fit (check the train/validation split)")
    return tuple(out)


# -- model structure -------------------------------------------------------------


def _model_features(m, u, dt):
    return m.features(u, dt)


def _hysteresis_set_weights(m, theta):
    return m.with_hysteresis(m.hysteresis.with_linear_weights(theta))


def _own_set_weights(m, theta):
    return m.with_linear_weights(theta)


def _linear_part(model):
    """``(features(model, u, dt), nonneg mask, with_weights(model, theta))`` or None.

    The model's output is ``features @ theta`` for fixed nonlinear parameters (its class says so:
    ``linear_in_weights``).  The weights are those of its hysteresis part (`smafl_jax.models._hysteresis`:
    a hysteresis model, a cascade, an extended model) or, for a model without one (`JouleLag`: static gain
    and offset), its own through the same methods.  Module-level functions, so jitted callers compile once
    per shape.
    """
    if not getattr(model, "linear_in_weights", False):
        return None
    h = hysteresis_of(model)
    if h is None:
        return _model_features, np.asarray(model.nonnegative_columns()), _own_set_weights
    return _model_features, np.asarray(h.nonnegative_columns()), _hysteresis_set_weights


def _has_k1(model):
    """A thermal stage whose rate ``model.thermal.k1`` the profile searches (cascade, Joule lag, extended cascade)."""
    return getattr(model, "thermal", None) is not None


def _set_k1(model, k1):
    return eqx.tree_at(lambda m: m.thermal.k1, model, jnp.asarray(k1, dtype=jnp.float64))


def default_trainable(model: eqx.Module, *, thresholds: bool = False, tilts: bool = False) -> Any:
    """PyTree of bools: train thermal k1 and the hysteresis weights, keep grids (EUPI: optionally train them).

    The hysteresis part says which of its fields stay fixed (`AbstractHysteresis.fixed_fields`);
    ``thresholds`` / ``tilts`` name its optional trainable groups.

    In a `Cascade` the hysteresis sees ``sqrt(theta k1 / k2)`` and ``theta`` is
    proportional to ``k2``, so the displacement does not depend on ``k2`` at all:
    it is structurally unidentifiable from input/displacement data and is held
    fixed.  ``k2`` (with ``k1``) is identified by fitting the `JouleLag`
    model (`JouleThermal` + offset) alone, as the paper does (eq. 7).
    """
    if hasattr(model, "trainable_spec"):  # a composite model that states its own rule (`ExtendedModel`); no load signal here
        return model.trainable_spec(load=False)
    spec = jax.tree_util.tree_map(eqx.is_inexact_array, model)
    h = hysteresis_of(model)
    if thermal_of(model) is not None:  # a thermal stage in front of a hysteresis: k2 cancels (see above)
        spec = eqx.tree_at(lambda s: s.thermal.k2, spec, False)
    if h is not None:
        train = [g for g, on in (("thresholds", thresholds), ("tilts", tilts)) if on]
        fixed = h.fixed_fields(train)
        spec = eqx.tree_at(lambda s: [getattr(s.hysteresis, f) for f in fixed], spec, [False] * len(fixed))
    return spec


# -- stage 1: linear / profiled initialiser ----------------------------------------


def _bvls(A, b, nonneg):
    """Bounded LS ``min |A x - b|`` with ``x[nonneg] >= 0``: `smafl_jax.identify.linear.solve`; returns ``(x, loss)``.

    The fit's options (`varpro.FIT_SOLVE`): column-scaled, Cholesky-reduced BVLS; operators the training samples
    never moved get gain 0; ``jitter_of="trace"`` and ``rhs="transpose"`` keep the fit's earlier numbers exactly.
    """
    from .linear import solve

    sol = solve(A, b, nonneg, **FIT_SOLVE)
    return sol.x, sol.loss


def _stack_rows(blocks, data, weights):
    """Weighted, zero-weight-rows-dropped design matrix and target over all records."""
    rows, targets = [], []
    for A, (_, y, _), w in zip(blocks, data, weights):
        keep = w > 0
        sw = np.sqrt(w[keep])
        rows.append(np.asarray(A)[keep] * sw[:, None])
        targets.append(y[keep] * sw)
    return np.concatenate(rows), np.concatenate(targets)


@eqx.filter_jit
def _features_jit(feats, model, u, dt):
    return feats(model, u, dt)


def _features(feats, model, u, dt):
    return _features_jit(feats, compile_form(model), u, dt)


def _check_finite_features(A, i, u):
    A = np.asarray(A)
    if np.all(np.isfinite(A)):
        return
    k = int(np.flatnonzero(~np.all(np.isfinite(A), axis=1))[0])
    raise UserInputError(
        f"record {i}: the model is not finite at sample {k} (input {u[k]:.6g}) at the initial parameters; "
        "is the input far outside the range the model was built for?"
    )


def init_linear(model: _Model, data: Any, dt: float | None = None, *, weights: Any = None) -> _Model:
    """Paper's constrained least squares for the linear gains, other parameters fixed.

    Returns a copy of ``model`` with the hysteresis weights (or, for `JouleLag`, the
    static gain and offset) replaced by the bounded least-squares solution
    (play-operator gains >= 0).
    """
    data = as_fit_data(data, dt, model=model)
    if isinstance(weights, np.ndarray) and weights.ndim == 1:  # one array over the concatenated rows
        weights = (
            np.split(weights, np.cumsum([u.shape[0] for u, _, _ in data])[:-1])
            if weights.shape[0] == sum(u.shape[0] for u, _, _ in data)
            else [weights]
        )
    weights = _as_weights(weights, data)
    part = _linear_part(model)
    if part is None:
        raise UserInputError(
            f"init_linear needs a model linear in its hysteresis weights (or a JouleLag), got {type(model).__name__}"
        )
    feats, nonneg, setw = part
    blocks = []
    for i, (u, _, d) in enumerate(data):
        A = _features(feats, record_model(model, i), jnp.asarray(u), jnp.asarray(d))
        _check_finite_features(A, i, u)
        blocks.append(A)
    A, b = _stack_rows(blocks, data, weights)
    theta, _ = _bvls(A, b, nonneg)
    return setw(model, jnp.asarray(theta))


def _default_k1_grid(data, n):
    """Log-spaced k1 candidates: time constants from dt/5 to 5x the longest record."""
    dt_min = min(d for _, _, d in data)
    t_max = max(d * u.shape[0] for u, _, d in data)
    return np.geomspace(0.2 / t_max, 5.0 / dt_min, int(n))


def _set_log_k1(model, log_k1):
    return _set_k1(model, np.exp(log_k1[0]))


def k1_projection(model: Any, data: tuple, weights: tuple, part: tuple | None = None) -> varpro.LinearProjection:
    """The fit's variable projection over ``x = [log k1]``: `varpro.LinearProjection` with the gains by BVLS.

    ``data`` / ``weights``: normalised (`as_fit_data`, `_as_weights`); ``part``: `_linear_part(model)` when known.
    Used by `init_profile` and by `smafl_jax.identify._choose.refine_thermal_start` (at each point's own k1).
    """
    feats, nonneg, setw = _linear_part(model) if part is None else part

    def design(m):
        blocks = [_features(feats, record_model(m, i), jnp.asarray(u), jnp.asarray(d)) for i, (u, _, d) in enumerate(data)]
        return _stack_rows(blocks, data, weights)

    return varpro.LinearProjection(lambda x: _set_log_k1(model, x), design, nonneg, setw, FIT_SOLVE)


def init_profile(
    model: _Model,
    data: Any,
    dt: float | None = None,
    *,
    weights: Any = None,
    k1_grid: int | ArrayLike = 32,
    refine: bool = True,
    xatol: float = 1e-7,
    progress: bool = False,
) -> tuple[_Model, dict[str, Any]]:
    """Variable-projection initialiser: best ``k1`` with the gains profiled out by BVLS.

    ``k1_grid`` is a number of log-spaced candidates (see `_default_k1_grid`) or
    an explicit array; the model's own ``k1`` is always tried as well.  The grid is
    evaluated in vmapped chunks, and the best candidate refined by a bounded 1-D
    search on ``log k1`` between its neighbours (`smafl_jax.identify.varpro.search`) to ``xatol`` in ``log k1``.
    Returns ``(model, info)`` with the grid, the profiled loss on it and the refined k1.
    """
    data = as_fit_data(data, dt, model=model)
    weights = _as_weights(weights, data)
    part = _linear_part(model)
    if part is None or not _has_k1(model):
        raise UserInputError(f"init_profile needs a model with a thermal k1 and linear gains, got {type(model).__name__}")
    feats, nonneg, setw = part
    grid = _default_k1_grid(data, k1_grid) if np.ndim(k1_grid) == 0 else np.asarray(k1_grid, dtype=np.float64)
    grid = np.unique(np.concatenate([grid, [float(model.thermal.k1)]]))
    if not np.all(np.isfinite(grid)) or np.any(grid <= 0):
        raise UserInputError("k1 candidates must be finite and > 0")
    n_rows = sum(u.shape[0] for u, _, _ in data)
    n_cols = int(np.shape(feats(record_model(model, 0), jnp.zeros(3), jnp.asarray(1.0)))[1])
    # chunk the vmapped grid so the stacked design matrices stay under ~64 MB
    chunk = int(max(1, min(grid.size, (64 << 20) // (8 * n_rows * n_cols))))
    t0 = time.perf_counter()

    def evaluate(ks, n):
        # one vmap over the thermal + operator scans for all k1 candidates of the chunk (padded to one shape)
        blocks = [
            np.asarray(
                varpro.batch_design(feats, _set_k1, record_model(model, i), jnp.asarray(ks), jnp.asarray(u), jnp.asarray(d))
            )
            for i, (u, _, d) in enumerate(data)
        ]
        out = np.full(n, np.inf)
        for j in range(n):
            sol = varpro.solve_gains(*_stack_rows([blk[j] for blk in blocks], data, weights), nonneg, FIT_SOLVE)
            if sol is not None:
                out[j] = sol.loss
        return out

    def report(done, total):
        say(f"  profile: {done}/{total} k1 candidates")

    losses = varpro.grid_losses(evaluate, grid, chunk, progress=report if progress else None)
    res = varpro.search(
        k1_projection(model, data, weights, part),
        grid,
        x_of=lambda k: np.array([np.log(k)]),
        losses=losses,
        refine=varpro.Bounded(xatol=xatol) if refine else None,
        none_finite="the model output is not finite for any k1 candidate; check the input units and range",
    )
    if res.profiled.model is None:
        raise UserInputError("the model output is not finite at the profiled k1; check the input units and range")
    k1 = float(np.exp(res.x[0]))
    info = {
        "k1_grid": grid.tolist(),
        "profile_loss": losses.tolist(),
        "k1": k1,
        "loss": float(res.profiled.loss),
        "at_grid_edge": bool(res.start in (0, grid.size - 1)),
        "n_refine_evals": res.n_evals,
        "seconds": time.perf_counter() - t0,
    }
    return res.profiled.model, info


# -- stage 2: joint refinement -------------------------------------------------------

from .._choices import SOLVERS  # noqa: E402  (defined there so `smafl fit --help` stays light)


def _residuals(model, args):
    # record i runs from its own start (`for_record`: a joint fit may hold one thermal start per record)
    return jnp.concatenate([jnp.sqrt(w) * (record_model(model, i).simulate(u, d) - y) for i, (u, y, d, w) in enumerate(args)])


_residuals_compiled = eqx.filter_jit(_residuals)


def _residuals_jit(model, args):
    return _residuals_compiled(compile_form(model), args)


def _make_optx_solver(name, rtol, atol, stall=True):
    """The optimistix solver ``name``; ``stall``: Gauss-Newton types also stop once their steps stop paying
    (`StallStop`)."""
    if name in ("lm", "gauss_newton"):
        inner = (optx.LevenbergMarquardt if name == "lm" else optx.GaussNewton)(rtol=rtol, atol=atol)
        return StallStop(inner) if stall else inner
    if name == "bfgs":
        return optx.BFGS(rtol=rtol, atol=atol)
    raise UserInputError(f"unknown solver {name!r}; choose one of {SOLVERS}")


#: Solvers whose steps `_solve_optx` counts for the progress estimate.
_COUNTED = ("lm", "gauss_newton", "bfgs")


@eqx.filter_jit
def _solve_optx(solver, raw_train, static, args, max_steps, count=True):
    def fn(p, a):
        if count:  # one per residual evaluation ~ one per step: progress with an estimate
            # a host callback keeps the program out of JAX's persistent cache, so it is left out when that cache is on
            jax.debug.callback(count_step)
        return _residuals(constrain(eqx.combine(p, static)), a)

    if isinstance(solver, optx.AbstractMinimiser):
        sol = optx.minimise(lambda p, a: 0.5 * jnp.sum(fn(p, a) ** 2), solver, raw_train, args, max_steps=max_steps, throw=False)
    else:
        sol = optx.least_squares(fn, solver, raw_train, args, max_steps=max_steps, throw=False)
    loss = 0.5 * jnp.sum(fn(sol.value, args) ** 2)
    ok = sol.result == optx.RESULTS.successful
    return sol.value, ok, sol.stats["num_steps"], loss, sol.stats.get("stalled", jnp.array(False))


@eqx.filter_jit
def _solve_jaxopt(name, params, static, bounds, args, max_steps, tol):
    import jaxopt
    from jaxopt.projection import projection_box

    def loss(p):
        return 0.5 * jnp.sum(_residuals(eqx.combine(p, static), args) ** 2)

    if name == "lbfgsb":
        solver = jaxopt.LBFGSB(fun=loss, maxiter=max_steps, tol=tol)
        sol = solver.run(params, bounds=bounds)
    else:
        solver = jaxopt.ProjectedGradient(fun=loss, projection=projection_box, maxiter=max_steps, tol=tol)
        sol = solver.run(params, hyperparams_proj=bounds)
    n = sol.state.iter_num
    return sol.params, n < max_steps, n, loss(sol.params)


def _lift_zero_gains(model, spec, profiled):
    """Give exact-zero play gains a small positive value so a refinement can move them.

    BVLS returns exact zeros; in softplus coordinates those sit at
    ``softplus^-1(1e-10)`` where the gradient is ~1e-10, i.e. pinned.  That is
    right after the k1 profile when only ``k1`` and the gains are trained (the
    zeros are then part of the joint optimum, by the KKT conditions of the
    profiled problem), but pins them for good when the start is not that
    optimum (a BVLS at some other k1, or thresholds / tilts that move): an
    operator switched off at the start k1 could never switch back on (seen:
    LM from the paper's k1 stalled at 27x the loss scipy reached).  Then they
    start at 1e-4 of the largest gain instead.
    """
    h = hysteresis_of(model)
    if h is None:
        return model
    hs = spec.hysteresis
    linear = set(h.linear_fields())
    grids = any(
        bool(np.any(getattr(hs, f.name)))
        for f in dataclasses.fields(h)
        if f.name not in linear and eqx.is_array(getattr(h, f.name))
    )
    k1 = _has_k1(model) and bool(spec.thermal.k1)
    if not (grids or (k1 and not profiled)):
        return model
    # on the host: exact operations, and no XLA program compiled per gain count (18 of them on the benchmark record)
    theta, nonneg = np.asarray(h.linear_weights()), np.asarray(h.nonnegative_columns())
    floor = 1e-4 * float(np.max(np.abs(theta[nonneg]), initial=0.0))
    return model.with_hysteresis(h.with_linear_weights(jnp.asarray(np.where(nonneg, np.maximum(theta, floor), theta))))


def _finite_tree(tree):
    return all(bool(np.all(np.isfinite(np.asarray(x)))) for x in jax.tree_util.tree_leaves(tree) if eqx.is_array(x))


def _bvls_gains(model, part, args):
    """``(model with its bounded least-squares gains, loss, gains)`` on the fit's weighted records ``args``."""
    feats, nonneg, setw = part
    data = [(np.asarray(u), np.asarray(y), d) for u, y, d, _ in args]
    weights = [np.asarray(w) for *_, w in args]
    blocks = [_features(feats, record_model(model, i), jnp.asarray(u), jnp.asarray(d)) for i, (u, _, d) in enumerate(data)]
    sol = varpro.solve_gains(*_stack_rows(blocks, data, weights), nonneg, FIT_SOLVE)
    if sol is None:
        return model, np.inf, None
    model = setw(model, jnp.asarray(sol.x))
    r = np.asarray(_residuals_jit(model, args))
    return model, 0.5 * float(r @ r), np.asarray(sol.x)


def _refine(model, spec, args, solver, max_steps, rtol, atol, stall=True):
    """Joint refinement; returns ``(model, loss, n_steps, ok, stalled)``."""
    stalled = False
    part = _linear_part(model) if solver == "varpro" else None
    if part is not None and hysteresis_of(model) is not None:
        gains = lambda m: _bvls_gains(m, part, args)
        fitted, loss, n, ok = refine_projected(
            model, spec, args, gains, part[0], max_steps=max_steps, rtol=rtol, atol=atol, stall=stall
        )
        return fitted, float(loss), int(n), bool(ok), False
    if solver == "varpro":  # no operator gains to project out (a Joule lag, a model not linear in its weights): plain LM
        solver = "lm"
    if solver in ("lm", "gauss_newton", "bfgs"):
        formed, formed_spec = compile_form_spec(model, spec)
        raw_train, static = eqx.partition(unconstrain(formed), formed_spec)
        solver_ = _make_optx_solver(solver, rtol, atol, stall)
        solve = _solve_optx(solver_, raw_train, static, args, max_steps, count=persistent_cache_dir() is None)
        value, ok, n, loss, stalled = solve
        fitted = user_form(constrain(eqx.combine(value, static)))
    elif solver in ("lbfgsb", "projected_gradient"):
        params, static = eqx.partition(model, spec)
        pos = eqx.filter(positive_mask(model), spec)
        lo = jax.tree_util.tree_map(lambda p, m: jnp.full_like(p, POSITIVE_FLOOR if m else -jnp.inf), params, pos)
        hi = jax.tree_util.tree_map(lambda p: jnp.full_like(p, jnp.inf), params)
        value, ok, n, loss = _solve_jaxopt(solver, params, static, (lo, hi), args, max_steps, atol)
        fitted = eqx.combine(value, static)
    else:
        raise UserInputError(f"unknown solver {solver!r}; choose one of {SOLVERS}")
    return fitted, float(loss), int(n), bool(ok), bool(stalled)


_INITS = ("auto", "profile", "linear", None)


@blas_limited
def fit(
    model: eqx.Module,
    data: Any,
    dt: float | None = None,
    *,
    solver: str | None = "lm",
    trainable: Any = None,
    init: str | None = "auto",
    max_steps: int = 300,
    rtol: float = 1e-6,
    atol: float = 1e-9,
    weights: Any = None,
    k1_grid: int | ArrayLike = 32,
    profile_xatol: float = 1e-7,
    gain_prior: float | None = None,
    stall: bool = True,
    pad: bool = True,
    progress: bool = False,
) -> FitResult:
    """Fit ``model`` to ``data`` (see `as_fit_data`); returns a `FitResult`.

    ``fit`` trains the parameters of ``model`` as given: its structure and its start-state rules (the thermal
    ``init``, the operator memory ``init``) stay what they are, so a record that does not start as those rules
    assume (e.g. a cold start fitted with the default ``init="steady"``) gets a poor fit that may still report
    converged.  For the full pipeline (start-state screening, the hysteresis input and class, a validation split)
    use `smafl_jax.report.fit_record` (what ``smafl fit`` runs; it takes a `Record`: ``sj.load_record(path)`` or
    ``sj.Record.from_arrays(t, u, y)``), or `smafl_jax.fit_records` for several records.
    ``dt``: the sample time in seconds, required with plain arrays unless the model is rate-independent (a
    hysteresis model on its own); a `Record` carries its own.  When the joint refinement does not lower the
    initialiser's loss, ``message`` and ``info["refinement_lowered_loss"]`` say so (with the training RMSE in output
    noise SDs, ``info["train_noise_ratio"]``), and a warning is logged; at INFO when that was to be expected (the
    initialiser already solved the trained problem, as in the default fit of an EUPI or a cascade, and the fit is within
    `NOISE_FLOOR_WARN` noise SDs) or the caller gave the start (``init=None``).

    ``init``: ``"profile"`` (variable projection over thermal ``k1``, see
    `init_profile`), ``"linear"`` (BVLS gains at the current thermal
    parameters), ``None`` (start from ``model`` as given) or ``"auto"``
    (profile when a thermal ``k1`` is trainable, else linear).  ``solver`` is
    one of `SOLVERS`, or None to stop after the initialiser; ``max_steps=0``
    does the same.  ``weights``: per-record sample weights (0 = held out, e.g.
    a validation mask; the model still runs through those samples so its
    memory stays continuous).  ``trainable`` defaults to
    `default_trainable(model)`.  ``k1_grid`` / ``profile_xatol``: the profile's k1
    candidates and the tolerance of its 1-D refinement in ``log k1`` (`init_profile`).
    ``gain_prior``: kappa of the prior on the operator gains (`smafl_jax.identify._gain_prior`: each operator gain
    ~ N(0, (kappa x output range)^2)); the returned gains are then the MAP at the fitted nonlinear parameters
    (``info["gain_prior"]`` says what it changed).  None (the default here): the least-squares gains.
    ``stall``: the Gauss-Newton-type solvers (lm, gauss_newton) also stop once the last `STALL_WINDOW` steps gained
    less than `STALL_MIN_GAIN` in log-likelihood (`StallStop`); False runs them to their own tolerance or ``max_steps``.
    ``pad``: the compiled programs see each record padded at its end to `smafl_jax.models.bucket_length` samples with
    weight 0 (`pad_records`), so that records of nearby lengths share one compilation (about 5 s per new length of a
    3 000-sample cascade fit); the fit is the same (the models are causal; a class with ``causal = False`` is never
    padded).  False compiles for every record length.
    """
    gain_prior = check_gain_prior(gain_prior)
    res = _fit(
        model, data, dt, solver=solver, trainable=trainable, init=init, max_steps=max_steps, rtol=rtol, atol=atol,
        weights=weights, k1_grid=k1_grid, profile_xatol=profile_xatol, stall=stall, pad=pad, progress=progress,
    )  # fmt: skip
    if gain_prior is None:
        return res
    part = _linear_part(res.model)
    if part is None or hysteresis_of(res.model) is None:  # no operator gains (a Joule lag): nothing for the prior
        return res
    feats, nonneg, setw = part
    data = as_fit_data(data, dt, model=model)
    lengths = [u.shape[0] for u, _, _ in data]
    data, weights = _padded(res.model, data, _as_weights(weights, data), pad)  # padded rows: weight 0, dropped below
    blocks = [_features(feats, record_model(res.model, i), jnp.asarray(u), jnp.asarray(d)) for i, (u, _, d) in enumerate(data)]
    if not all(np.all(np.isfinite(np.asarray(A)[:n])) for A, n in zip(blocks, lengths)):
        return res
    A, b = _stack_rows(blocks, data, weights)
    theta, info = map_gains(A, b, nonneg, gain_prior)
    say(
        f"gain prior (kappa {gain_prior:g}): largest operator gain {info['largest_gain_free']:.4g} -> "
        f"{info['largest_gain']:.4g}, training RMSE {info['rmse_free']:.4g} -> {info['rmse']:.4g}"
        + (f"; {info['weak_columns']} barely moving operator column(s) at gain 0" if info["weak_columns"] else ""),
        progress,
    )
    model = setw(res.model, jnp.asarray(theta))
    return res._replace(model=model, loss=0.5 * float(len(b)) * info["rmse"] ** 2, info={**(res.info or {}), "gain_prior": info})


def _padded(model, data, weights, pad):
    """``(data, weights)`` padded at the end (`pad_records`) when ``pad`` is on and ``model`` is causal, else as given.

    The class says whether it may be padded (``causal``, default True: every model here, effects included, is causal,
    as `smafl_jax.models.padded_call` in the diagnosis assumes too)."""
    if not (pad and getattr(model, "causal", True)):
        return data, weights
    return pad_records(data, weights)


def _fit(
    model, data, dt=None, *, solver, trainable, init, max_steps, rtol, atol, weights, k1_grid, profile_xatol, stall, progress,
    pad=True,
) -> FitResult:  # fmt: skip
    """`fit` without the gain prior.

    The programs see ``padded`` / ``pweights`` (`_padded`: zero-weight samples at the end of each record, dropped by
    `_stack_rows` and zeroed by `_residuals`); what depends on the record itself (the default k1 grid: its duration;
    the noise estimate: its outputs) is taken from the records as given."""
    release_if_needed()  # long sessions compile many programs: stay under the memory-map limit (`_compile_cache`)
    asked = init
    if init not in _INITS:
        raise UserInputError(f"init must be one of {_INITS}, got {init!r}")
    own_start = init is not None  # fit makes its own start (else the caller gave it, and gates on the result itself)
    if solver is not None and solver not in SOLVERS:
        raise UserInputError(f"unknown solver {solver!r}; choose one of {SOLVERS}")
    if not (isinstance(max_steps, (int, np.integer)) and max_steps >= 0):
        raise UserInputError(f"max_steps must be an integer >= 0, got {max_steps!r}")
    template = model
    data = as_fit_data(data, dt, model=model)
    weights = _as_weights(weights, data)
    padded, pweights = _padded(model, data, weights, pad)
    spec = default_trainable(model) if trainable is None else trainable
    info = {}
    t0 = time.perf_counter()
    k1_trainable = _has_k1(model) and bool(spec.thermal.k1)
    if init == "auto":
        init = (
            "profile"
            if (k1_trainable and _linear_part(model) is not None)
            else ("linear" if _linear_part(model) is not None else None)
        )
    if init == "profile":
        say(
            f"initialiser: profiling k1 ({k1_grid if np.ndim(k1_grid) == 0 else len(k1_grid)} candidates, gains by bounded LS)",
            progress,
        )
        grid = _default_k1_grid(data, k1_grid) if np.ndim(k1_grid) == 0 else k1_grid  # the records' own durations
        model, info["profile"] = init_profile(
            model, padded, weights=pweights, k1_grid=grid, xatol=profile_xatol, progress=progress
        )
    elif init == "linear":
        say("initialiser: bounded least squares for the gains", progress)
        model = init_linear(model, padded, weights=list(pweights))
    info["init"] = init
    info["init_seconds"] = time.perf_counter() - t0
    args = tuple((jnp.asarray(u), jnp.asarray(y), jnp.asarray(d), jnp.asarray(w)) for (u, y, d), w in zip(padded, pweights))
    res0 = np.asarray(_residuals_jit(model, args))
    if padded is not data and not np.all(np.isfinite(res0)):
        # not finite somewhere: refit unpadded, which names the sample in the records as given (or fits, when only
        # the padding, the last input held, was not finite)
        return _fit(
            template, data, solver=solver, trainable=trainable, init=asked, max_steps=max_steps, rtol=rtol,
            atol=atol, weights=weights, k1_grid=k1_grid, profile_xatol=profile_xatol, stall=stall, progress=progress,
            pad=False,
        )  # fmt: skip
    if not np.all(np.isfinite(res0)):
        k = int(np.flatnonzero(~np.isfinite(res0))[0])
        raise UserInputError(
            f"the model output is not finite at the start of the fit (sample {k} of the concatenated records); "
            "check the input units against the model's range and the initial parameters"
        )
    init_loss = 0.5 * float(res0 @ res0)
    if solver is None or max_steps == 0:
        info["total_seconds"] = time.perf_counter() - t0
        how = init if init is not None else "the start as given: no initialiser, no refinement"
        return FitResult(model, init_loss, 0, True, f"initialiser only ({how})", "none", init_loss, info)
    start = _lift_zero_gains(model, spec, profiled=init == "profile")
    say(f"joint refinement: {solver}, up to {max_steps} steps", progress)
    t1 = time.perf_counter()
    counted = max_steps if solver in _COUNTED and persistent_cache_dir() is None else None
    with shown(progress), heartbeat(f"joint refinement ({solver})", enabled=progress, max_steps=counted):
        fitted, loss, n_steps, ok, stalled = _refine(start, spec, args, solver, max_steps, rtol, atol, stall)
    info["refine_seconds"] = time.perf_counter() - t1
    info["total_seconds"] = time.perf_counter() - t0
    finite = np.isfinite(loss) and _finite_tree(fitted)
    if not finite:
        message = (
            f"joint refinement ({solver}) diverged: the loss or a parameter became NaN/inf after {n_steps} steps "
            f"(a step left the region where the model is finite); kept the initialiser's model (loss {init_loss:.6g})"
        )
        return FitResult(model, init_loss, n_steps, False, message, solver, init_loss, info)
    # "worse" beyond round-off: relative to the start loss and to the signal energy (exact fits end near 0)
    energy = 0.5 * sum(float(np.sum(w * y * y)) for (_, y, _), w in zip(data, weights))
    gained = _refinement_gained(loss, init_loss, energy)
    info["refinement_lowered_loss"] = gained
    solved = not gained and _initialiser_solves(model, spec, init)
    ratio = None if gained else _noise_ratio(data, weights, loss)
    if ratio is not None:
        info["train_noise_ratio"] = ratio
    poor = ratio is not None and ratio > NOISE_FLOOR_WARN
    if not gained:
        level = logging.WARNING if own_start and (poor or not solved) else logging.INFO
        steps = f"{solver}, {n_steps} steps, loss {init_loss:.10g} -> {loss:.10g}"
        logger.log(level, "fit: %s", _no_gain_words(steps, solved, ratio if poor else None, level >= logging.WARNING))
    if loss > init_loss * (1 + 1e-9) + 1e-13 * energy:
        if ok and loss <= init_loss * (1 + NEAR_START_RTOL):
            # the solver met its tolerance next to the initialiser (it starts from lifted gains, `_lift_zero_gains`): the
            # kept initialiser is as good a fit, and "not converged" there sent users hunting a failure that was not one
            message = (
                f"converged: {solver} met its tolerance after {n_steps} steps at a loss {loss / init_loss - 1:.2g} "
                f"(relative) above the initialiser's ({loss:.10g} > {init_loss:.10g}); kept the initialiser's model"
            )
            return FitResult(model, init_loss, n_steps, True, message, solver, init_loss, info)
        message = (
            f"joint refinement ({solver}) ended worse than its start (loss {loss:.10g} > {init_loss:.10g}); "
            "kept the initialiser's model"
        )
        return FitResult(model, init_loss, n_steps, False, message, solver, init_loss, info)
    if stalled:
        message = (
            f"converged: {solver} stopped after {n_steps} steps, the last {STALL_WINDOW} of which gained less than "
            f"{STALL_MIN_GAIN:g} in log-likelihood"
        )
    elif ok:
        message = "converged"
    else:
        message = f"{solver} stopped after {n_steps} steps without meeting its tolerance (max_steps={max_steps})"
    if not gained:
        message += "; " + _no_gain_words(f"loss {init_loss:.10g} -> {loss:.10g}", solved, ratio if poor else None, False)
    return FitResult(fitted, loss, n_steps, ok, message, solver, init_loss, info)


#: A refinement that met its tolerance at most this much (relative) above the initialiser's loss keeps the initialiser
#: and counts as converged: a new-user trial saw ``converged=False`` on good fits whose LM ended 1e-4 above it.
NEAR_START_RTOL = 1e-3
#: What `FitResult.message` adds when the joint refinement did not lower the initialiser's loss.
NO_GAIN = "the joint refinement did not lower the loss below the initialiser's"
#: ... and why, when the initialiser already solved the trained problem (`_initialiser_solves`).
SOLVED = "the initialiser is already the least-squares optimum of the trained parameters (the gains, with k1 after the profile)"


def _refinement_gained(loss: float, init_loss: float, energy: float) -> bool:
    """Whether the refinement ended below its start beyond round-off (the tolerances of the "ended worse" test); a
    start already at round-off of an exact fit counts as gained (there is nothing left to lower)."""
    return bool(loss < init_loss * (1 - 1e-9) - 1e-13 * energy) or init_loss <= 1e-13 * energy


def _initialiser_solves(model: Any, spec: Any, init: str | None) -> bool:
    """Whether the initialiser ``init`` already solved the problem ``spec`` trains: ``"linear"`` with only the
    hysteresis gains trained (bounded least squares is exact), ``"profile"`` with only those and ``k1`` (the variable
    projection is the joint optimum).  Then a refinement has nothing to lower, and its not lowering is no news."""
    h = hysteresis_of(model)
    if init not in ("linear", "profile") or h is None:
        return False
    try:
        ref = jax.tree_util.tree_map(lambda _: False, spec)
        fields = list(h.linear_fields())
        ref = eqx.tree_at(lambda s: [getattr(hysteresis_of(s), f) for f in fields], ref, [True] * len(fields))
        if init == "profile":
            ref = eqx.tree_at(lambda s: s.thermal.k1, ref, True)
    except (AttributeError, TypeError, ValueError):  # a spec that does not mirror the model: say nothing special
        return False
    trained, allowed = jax.tree_util.tree_leaves(spec), jax.tree_util.tree_leaves(ref)
    if len(trained) != len(allowed):
        return False
    return not any(np.any(np.asarray(t)) and not np.all(np.asarray(a)) for t, a in zip(trained, allowed))


def _noise_ratio(data: tuple, weights: tuple, loss: float) -> float | None:
    """Training RMSE over the output's noise SD estimated from the measured outputs (`noise_floor`); None if unknown."""
    n = sum(float(np.sum(w)) for w in weights)
    sd = noise_floor([y for _, y, _ in data])["sd"]
    if not (n > 0 and sd > 0 and np.isfinite(loss)):
        return None
    return float(np.sqrt(2.0 * loss / n) / sd)


def _no_gain_words(what: str, solved: bool, poor: float | None, long: bool) -> str:
    """Why a refinement did not lower the loss (`NO_GAIN`, ``what``: the numbers), for `FitResult.message` and the log.

    The log line is a WARNING (``long``: with the way out) when fit made its own start and either the refinement had
    something to do (not `_initialiser_solves`) or the fit stays above `NOISE_FLOOR_WARN` output-noise SDs (``poor``: the
    ratio); else INFO: the initialiser already solved the trained problem of a fit at the noise (every default fit of
    an EUPI or a cascade ends so), or the caller gave the start (``init=None``: the library's own pipelines refine a
    screened start and keep the better of the two themselves, e.g. the diagnosis's `refine_model`: 11 such lines in one
    ``smafl diagnose`` run otherwise)."""
    words = f"{NO_GAIN} ({what})" + (f": {SOLVED}" if solved else "")
    if poor is not None:
        words += (
            f"; training RMSE {poor:.3g}x the output's noise SD (estimated from the data): the model's start state or "
            "structure may not suit this record"
        )
    if long:
        return words + (
            ". The start state and the structure stay as given (fit does not choose them): for a record that does not "
            "start at rest with its first input, or to choose the structure, smafl_jax.report.fit_record("
            "sj.Record.from_arrays(t, u, y)) (what `smafl fit` runs) screens both"
        )
    return words + "; the start state and the structure are as given (smafl_jax.report.fit_record screens them)"


@blas_limited
def fit_many(
    model: eqx.Module,
    datasets: Iterable[Any],
    *,
    weights: Sequence[Any] | None = None,
    progress: bool = True,
    names: Sequence[str] | None = None,
    **kwargs: Any,
) -> list[FitResult | UserInputError]:
    """Fit one model template to many records or actuators; returns a list of `FitResult` (or the error).

    Each entry of ``datasets`` is anything `fit` accepts for one actuator.
    Records whose lengths share a `smafl_jax.models.bucket_length` reuse the same compiled code (`fit` pads them; one
    compile per bucket); the k1 profile inside each fit is one `vmap` over candidates.
    A record that cannot be fitted gives its `UserInputError` in the list
    instead of stopping the batch; its message names the entry: ``fit data 'run_03' (3): ...`` with ``names``, else
    ``fit data 3: ...`` (its place in ``datasets``).  ``progress``: one line per record on the progress logger, shown on
    stderr unless logging is configured (`smafl_jax._progress.shown`).
    """
    datasets = list(datasets)
    weights = [None] * len(datasets) if weights is None else list(weights)
    if names is not None:
        names = [str(n) for n in names]
    for what, given in (("weights", weights), ("names", names)):
        if given is not None and len(given) != len(datasets):  # zip would silently drop the records beyond the shorter
            raise UserInputError(f"fit_many: got {len(given)} {what} for {len(datasets)} datasets")
    out = []
    t0 = time.perf_counter()
    for i, (d, w) in enumerate(zip(datasets, weights)):
        name = None if names is None else names[i]
        try:
            # checked here, where the entry's place and name are known (inside `fit` every entry is record 0)
            label = _fit_label(i, name)
            items = _fit_items(d, label)
            labels = [label] if len(items) == 1 else [f"{label}, record {j}" for j in range(len(items))]
            r = fit(model, _normalised(items, kwargs.get("dt"), model, labels), weights=w, **kwargs)
        except UserInputError as exc:
            r = exc
        out.append(r)
        if progress:
            status = f"loss {r.loss:.4g}, {r.message}" if isinstance(r, FitResult) else f"failed: {r}"
            el = time.perf_counter() - t0
            say(f"[{i + 1}/{len(datasets)}] {name or f'#{i}'}: {status} ({el:.1f} s elapsed)")
    return out


def replace(model, **changes):
    """Functional field update for model PyTrees (thin wrapper over dataclasses.replace)."""
    return dataclasses.replace(model, **changes)
