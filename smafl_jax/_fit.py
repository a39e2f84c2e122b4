"""Core of the identification: linear initialiser + joint gradient-based refinement.

Two stages, as in the paper and beyond it:

1. `init_linear`: for fixed thresholds, tilts and thermal parameters the EUPI
   is linear in its gains, so the paper's constrained least squares (gains of
   the play operators >= 0, polynomial and offset free) is solved exactly with
   `scipy.optimize.lsq_linear` (bounded-variable least squares).
2. `fit`: all trainable parameters (thermal k1, k2 and the EUPI gains by
   default; thresholds and tilts optionally) refined jointly through the scan by
   an optimistix least-squares solver, in unconstrained coordinates (positive
   fields through softplus, resolved inside the residual function).

Which leaves are trained is a PyTree of bools (`default_trainable`); the rest
are held fixed with `equinox.partition` / `equinox.combine`.
"""

from __future__ import annotations

import dataclasses
from typing import Any, NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx

from . import _config  # noqa: F401
from ._cascade import Cascade
from ._constraints import constrain, unconstrain
from ._errors import UserInputError
from ._eupi import EUPI

__all__ = ["FitResult", "fit", "init_linear", "default_trainable", "as_fit_data"]


class FitResult(NamedTuple):
    """Outcome of `fit`: the physical model and how the solver got there."""

    model: Any
    loss: float  # 0.5 * sum of squared residuals over all records
    n_steps: int
    converged: bool
    message: str
    solver: str


def as_fit_data(data, dt=None):
    """Normalise fit data to a tuple of ``(u, y, dt)`` float64 numpy triples.

    Accepts a `Record`, a sequence of `Record`, a ``(u, y)`` pair with ``dt``,
    or a sequence of ``(u, y, dt)`` triples.
    """
    from ._data import Record

    if isinstance(data, Record):
        data = [data]
    elif isinstance(data, tuple) and len(data) == 2 and np.ndim(data[0]) == 1:
        data = [(data[0], data[1], dt)]
    out = []
    for i, item in enumerate(data):
        if isinstance(item, Record):
            if item.y is None:
                raise UserInputError(f"record {i} ({item.name}) has no output column to fit")
            u, y, d = item.u, item.y, item.dt
        else:
            u, y, d = item if len(item) == 3 else (*item, dt)
        u = np.asarray(u, dtype=np.float64)
        y = np.asarray(y, dtype=np.float64)
        if u.ndim != 1 or u.shape != y.shape:
            raise UserInputError(f"fit data {i}: input and output must be 1-D of equal length, got {u.shape} and {y.shape}")
        if u.shape[0] < 3:
            raise UserInputError(f"fit data {i}: need at least 3 samples, got {u.shape[0]}")
        if not (np.all(np.isfinite(u)) and np.all(np.isfinite(y))):
            raise UserInputError(f"fit data {i}: non-finite values in input or output")
        d = 1.0 if d is None else float(d)
        if not d > 0:
            raise UserInputError(f"fit data {i}: sample time must be > 0, got {d}")
        out.append((u, y, d))
    if not out:
        raise UserInputError("no data to fit")
    return tuple(out)


def _eupi_of(model):
    if isinstance(model, EUPI):
        return model
    if isinstance(model, Cascade):
        return model.hysteresis
    return getattr(model, "hysteresis", None)


def _hysteresis_input(model, u, dt):
    """Signal the EUPI of ``model`` sees for drive ``u`` (identity for a bare EUPI)."""
    if isinstance(model, EUPI):
        return jnp.asarray(u)
    if hasattr(model, "hysteresis_input"):
        return model.hysteresis_input(u, dt)
    return model.thermal.effective_voltage(model.thermal.simulate(u, dt))


def _replace_eupi(model, eupi):
    if isinstance(model, EUPI):
        return eupi
    return eqx.tree_at(lambda m: m.hysteresis, model, eupi)


def init_linear(model, data, dt=None, *, weights=None):
    """Paper's constrained least squares for the EUPI gains, other parameters fixed.

    Returns a copy of ``model`` with the EUPI gains replaced by the bounded
    least-squares solution (play-operator gains >= 0).
    """
    from scipy.optimize import lsq_linear

    data = as_fit_data(data, dt)
    eupi = _eupi_of(model)
    if eupi is None:
        raise UserInputError(f"init_linear needs a model with an EUPI part, got {type(model).__name__}")
    rows, targets = [], []
    for u, y, d in data:
        x = _hysteresis_input(model, u, d)
        rows.append(np.asarray(eupi.features(x)))
        targets.append(y)
    A = np.concatenate(rows)
    b = np.concatenate(targets)
    if weights is not None:
        w = np.sqrt(np.asarray(weights, float))
        A, b = A * w[:, None], b * w
    nonneg = eupi.nonnegative_columns()
    lb = np.where(nonneg, 0.0, -np.inf)
    # column scaling keeps BVLS well conditioned when operator columns are tiny
    scale = np.maximum(np.sqrt(np.mean(A**2, axis=0)), 1e-12)
    sol = lsq_linear(A / scale, b, bounds=(lb, np.full_like(lb, np.inf)), method="bvls")
    theta = sol.x / scale
    return _replace_eupi(model, eupi.with_linear_weights(theta))


def default_trainable(model, *, thresholds=False, tilts=False):
    """PyTree of bools: train thermal k1 and EUPI gains, keep grids (optionally train them).

    In a `Cascade` the hysteresis sees ``sqrt(theta k1 / k2)`` and ``theta`` is
    proportional to ``k2``, so the displacement does not depend on ``k2`` at all:
    it is structurally unidentifiable from input/displacement data and is held
    fixed.  ``k2`` (with ``k1``) is identified by fitting the `JouleThermal`
    model alone, as the paper does (U^2 -> displacement, eq. 7).
    """
    spec = jax.tree_util.tree_map(eqx.is_inexact_array, model)
    if isinstance(getattr(model, "thermal", None), eqx.Module) and hasattr(model.thermal, "k2") and _eupi_of(model) is not None:
        spec = eqx.tree_at(lambda s: s.thermal.k2, spec, False)
    eupis = []
    if isinstance(model, EUPI):
        eupis = [lambda m: m]
    elif _eupi_of(model) is not None:
        eupis = [lambda m: m.hysteresis]
    for get in eupis:
        fixed = ["u_ref", "u_span"] + ([] if thresholds else ["r_sym", "r_asym"]) + ([] if tilts else ["alpha"])
        spec = eqx.tree_at(lambda s: [getattr(get(s), f) for f in fixed], spec, [False] * len(fixed))
    return spec


def _residual_fn(static, data):
    def residuals(raw_train, args):
        model = constrain(eqx.combine(raw_train, static))
        res = [model.simulate(u, d) - y for u, y, d in args]
        return jnp.concatenate(res)

    return residuals


_SOLVERS = ("lm", "gauss_newton", "bfgs")


def _make_solver(name, rtol, atol):
    if name == "lm":
        return optx.LevenbergMarquardt(rtol=rtol, atol=atol)
    if name == "gauss_newton":
        return optx.GaussNewton(rtol=rtol, atol=atol)
    if name == "bfgs":
        return optx.BFGS(rtol=rtol, atol=atol)
    raise UserInputError(f"unknown solver {name!r}; choose one of {_SOLVERS}")


@eqx.filter_jit
def _solve(solver, raw_train, static, args, max_steps):
    fn = _residual_fn(static, None)
    if isinstance(solver, optx.AbstractMinimiser):
        sol = optx.minimise(lambda p, a: 0.5 * jnp.sum(fn(p, a) ** 2), solver, raw_train, args, max_steps=max_steps, throw=False)
    else:
        sol = optx.least_squares(fn, solver, raw_train, args, max_steps=max_steps, throw=False)
    loss = 0.5 * jnp.sum(fn(sol.value, args) ** 2)
    return sol.value, sol.result, sol.stats["num_steps"], loss


def fit(model, data, dt=None, *, solver="lm", trainable=None, init="linear", max_steps=300, rtol=1e-8, atol=1e-10):
    """Fit ``model`` to ``data`` (see `as_fit_data`) jointly; returns a `FitResult`.

    ``init="linear"`` first solves the paper's constrained least squares for
    the EUPI gains at the current thermal parameters; ``init=None`` starts from
    ``model`` as given.  ``trainable`` defaults to `default_trainable(model)`.
    """
    data = as_fit_data(data, dt)
    if init == "linear" and _eupi_of(model) is not None:
        model = init_linear(model, data)
    elif init not in (None, "linear"):
        raise UserInputError(f"init must be 'linear' or None, got {init!r}")
    spec = default_trainable(model) if trainable is None else trainable
    raw = unconstrain(model)
    raw_train, static = eqx.partition(raw, spec)
    args = tuple((jnp.asarray(u), jnp.asarray(y), jnp.asarray(d)) for u, y, d in data)
    value, result, n_steps, loss = _solve(_make_solver(solver, rtol, atol), raw_train, static, args, max_steps)
    fitted = constrain(eqx.combine(value, static))
    loss = float(loss)
    ok = result == optx.RESULTS.successful
    finite = np.isfinite(loss) and all(np.all(np.isfinite(np.asarray(x))) for x in jax.tree_util.tree_leaves(fitted))
    if not finite:
        message = "fit diverged: the loss or a parameter became NaN/inf (check input scaling and the initial thermal parameters)"
    elif ok:
        message = "converged"
    else:
        message = f"solver stopped without converging: {optx.RESULTS[result] if hasattr(optx.RESULTS, '__getitem__') else result}"
    return FitResult(fitted, loss, int(n_steps), bool(ok and finite), message, solver)


def replace(model, **changes):
    """Functional field update for model PyTrees (thin wrapper over dataclasses.replace)."""
    return dataclasses.replace(model, **changes)
