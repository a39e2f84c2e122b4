"""Variable projection: the one search over nonlinear parameters with the linear gains profiled out.

Every identification in the toolkit is linear in most of its parameters (hysteresis weights, offsets,
linear effect fields) once a few nonlinear ones are fixed (thermal rate ``k1``, a start voltage ``u0``,
effect time constants...).  Variable projection solves the linear part exactly for each value of the
nonlinear parameters (`smafl_jax.identify.linear.solve`, bounds and signs exact) and searches only the
nonlinear ones, in transformed coordinates ``x`` (log of a positive parameter, ...):

1. a *projection* ``project(x, start) -> Profiled(loss, model)``: the model at the nonlinear parameters
   ``x`` with its optimal gains (`LinearProjection` for the plain linear case; the diagnosis passes its
   own, which adds a Gauss-Newton finish under a nonlinear output map);
2. `search`: the loss of every start of a grid (`grid_losses` evaluates a grid in fixed-shape chunks, the
   designs of a chunk in one vmapped call, `batch_design`), the best start (the first minimum), then a
   refinement from it (`Bounded`: a 1-D bounded Brent search between the best start's grid neighbours;
   `NelderMead`: a simplex search with the caller's steps, caps and tolerances) and the projection at
   the chosen point.

Used by `smafl_jax.identify._fit.init_profile` (k1 grid + `Bounded`), `smafl_jax.identify._choose.
refine_thermal_start` (``(log k1, u0)`` by `NelderMead`) and `smafl_jax.diagnosis._diagnose.fit_extended`
(effect grid x k1 grid + `NelderMead`).  Each keeps its earlier numbers exactly: the options below are
those each caller always used, and the engine evaluates in the same order.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._errors import UserInputError
from ..models._simulate import compile_form
from .linear import LinearSolution, solve

__all__ = [
    "FIT_SOLVE",
    "DIAGNOSE_SOLVE",
    "Profiled",
    "LinearProjection",
    "solve_gains",
    "batch_design",
    "grid_losses",
    "best_start",
    "Bounded",
    "NelderMead",
    "Search",
    "search",
]

#: `linear.solve` options of the fit (`init_linear`, `init_profile`): operators the training samples never moved get
#: gain 0 (``drop_constant``); the trace-relative jitter and LAPACK's transposed solve keep the fit's earlier numbers.
FIT_SOLVE: Mapping[str, Any] = {"jitter": 1e-13, "jitter_of": "trace", "rhs": "transpose", "drop_constant": True}
#: `linear.solve` options of the diagnosis (`profile_gains`): defaults, no ``clip`` (its earlier numbers).
DIAGNOSE_SOLVE: Mapping[str, Any] = {"clip": False}


@dataclasses.dataclass(frozen=True)
class Profiled:
    """A projection's result: ``loss`` (the caller's objective; inf where the model is not finite) and the model
    with its optimal gains (None where the loss is not finite)."""

    loss: float
    model: Any = None


def solve_gains(A, b, nonneg, options: Mapping[str, Any]) -> LinearSolution | None:
    """`linear.solve` with the caller's options, or None when ``A`` has a non-finite entry (the model left the
    region where it is finite at these nonlinear parameters: the search must see an infinite loss, not an error)."""
    A = np.asarray(A)
    if not np.all(np.isfinite(A)):
        return None
    return solve(A, b, nonneg, **options)


@dataclasses.dataclass(frozen=True)
class LinearProjection:
    """``x -> Profiled(0.5 |A theta - b|^2, model)``: the model at the nonlinear parameters ``x`` with its gains.

    ``build(x)``: the model at ``x`` (gains arbitrary); ``design(model)``: its stacked (weighted) design matrix
    and target ``(A, b)``; ``nonneg``: the columns whose gains are >= 0; ``set_gains(model, theta)``: the model
    with gains ``theta``; ``options``: `linear.solve` options (`FIT_SOLVE`, `DIAGNOSE_SOLVE`).
    """

    build: Callable[[np.ndarray], Any]
    design: Callable[[Any], tuple[np.ndarray, np.ndarray]]
    nonneg: np.ndarray
    set_gains: Callable[[Any, jax.Array], Any]
    options: Mapping[str, Any] = dataclasses.field(default_factory=lambda: dict(FIT_SOLVE))

    def __call__(self, x: np.ndarray, start: Any = None) -> Profiled:
        """Profile at ``x`` (``start``, the grid start the search came from, is not needed here)."""
        del start
        model = self.build(x)
        A, b = self.design(model)
        sol = solve_gains(A, b, self.nonneg, self.options)
        if sol is None:
            return Profiled(np.inf, None)
        return Profiled(sol.loss, self.set_gains(model, jnp.asarray(sol.x)))


def _batch_design(design, build, template, values, *args):
    # one vmap over the candidates' scans (thermal + operators): the designs of a whole grid chunk in one call
    return jax.vmap(lambda v: design(build(template, v), *args))(values)


# One trace per (design, build, shapes); the counter lets tests check that new values never retrace.
_batch_design_traced = eqx.debug.assert_max_traces(_batch_design, max_traces=None)
_batch_design_jit = eqx.filter_jit(_batch_design_traced)


def batch_design(design: Callable, build: Callable, template: Any, values: jax.Array, *args: Any) -> jax.Array:
    """``design(build(template, v), *args)`` for every ``v`` in ``values`` (leading axis), in one vmapped, jitted call.

    ``design`` and ``build`` should be module-level functions: they are static, so equal shapes compile once.
    """
    return _batch_design_jit(design, build, compile_form(template), values, *args)


def grid_losses(
    evaluate: Callable[[np.ndarray, int], np.ndarray],
    points: np.ndarray,
    chunk: int | None = None,
    *,
    progress: Callable[[int, int], None] | None = None,
) -> np.ndarray:
    """Losses of the grid ``points``, evaluated in chunks of ``chunk`` (default: all at once).

    ``evaluate(chunk_points, n)`` gets ``chunk`` points (the last chunk padded with its last point, so every chunk
    has one shape and a vmapped evaluation compiles once) and returns the losses of the first ``n``.
    ``progress(done, total)`` is called after each chunk.
    """
    points = np.asarray(points)
    total = points.shape[0]
    chunk = total if chunk is None else int(max(1, min(total, chunk)))
    losses = np.full(total, np.inf)
    for start in range(0, total, chunk):
        pts = points[start : start + chunk]
        n = pts.shape[0]
        if n < chunk:
            pts = np.concatenate([pts, np.repeat(pts[-1:], chunk - n, axis=0)])
        losses[start : start + n] = evaluate(pts, n)
        if progress is not None:
            progress(min(start + chunk, total), total)
    return losses


def best_start(losses: Sequence[float]) -> int:
    """Index of the first minimum of ``losses`` (NaN counts as +inf)."""
    losses = np.asarray(losses, dtype=np.float64)
    return int(np.argmin(np.where(np.isnan(losses), np.inf, losses)))


@dataclasses.dataclass(frozen=True)
class Bounded:
    """1-D refinement: bounded Brent search (scipy ``minimize_scalar``) between the best start's neighbours in the
    (sorted) start list, to ``xatol``; skipped when the best start is at an end of the grid.  Its point is kept only
    when its loss is not above the best start's (Brent never evaluates the start itself)."""

    xatol: float = 1e-7


@dataclasses.dataclass(frozen=True)
class NelderMead:
    """Nelder-Mead refinement (scipy) from the best start: initial simplex the start and one vertex ``steps[i]``
    along each coordinate; ``maxiter`` / ``maxfev`` / ``xatol`` / ``fatol`` as scipy's options (None: scipy's
    default).  ``cache_decimals``: memoise the loss on ``x`` rounded to that many decimals (the simplex revisits
    points); ``bad``: the value a non-finite loss is replaced with.  Its final point is always taken: the start is
    a vertex of the simplex, so it is never worse as the search saw it.  ``n_starts``: the simplex runs from each of
    the ``n_starts`` best scored starts (ties in start order) and the lowest final loss is kept (the first of equal
    ones): a grid whose best start lies in the wrong basin (an effect's sign, a time constant at its bound) is refined
    from its runners-up too.  ``retry_if(x)``: with it, the runners-up are refined only when the best start's final
    point satisfies it (e.g. a parameter at its bound: a simplex that ends there found no interior minimum); None:
    always."""

    steps: Sequence[float]
    xatol: float = 1e-4
    fatol: float = 1e-10
    maxiter: int | None = None
    maxfev: int | None = None
    cache_decimals: int | None = None
    bad: float = np.inf
    n_starts: int = 1
    retry_if: Callable[[np.ndarray], bool] | None = None

    def __post_init__(self):
        if int(self.n_starts) < 1:
            raise ValueError(f"n_starts must be >= 1, got {self.n_starts!r}")


@dataclasses.dataclass(frozen=True)
class Search:
    """Outcome of `search`.

    ``x``: the chosen nonlinear parameters (refined, or the best start's); ``profiled``: the projection at ``x``
    (None when `search` was asked not to project again); ``best_seen``: the lowest loss the refinement evaluated
    (the first of equal ones) with its model, ``Profiled(inf)`` before any; ``start``: index of the best start;
    ``start_losses``: the starts' losses (None when a single start was not scored); ``n_evals``: the refinement's
    projections (distinct points when cached); ``converged``: scipy's success flag (True without refinement);
    ``refined``: whether ``x`` came from the refinement; ``n_runs``: simplex runs (more than one where the runners-up
    were refined, `NelderMead.n_starts`).
    """

    x: np.ndarray
    profiled: Profiled | None
    best_seen: Profiled
    start: int
    start_losses: np.ndarray | None
    n_evals: int
    converged: bool
    refined: bool
    n_runs: int = 0


def search(
    project: Callable[[np.ndarray, Any], Profiled],
    starts: Sequence[Any],
    *,
    x_of: Callable[[Any], np.ndarray],
    losses: Sequence[float] | None = None,
    score: Callable[[Any], float] | None = None,
    refine: Bounded | NelderMead | None = None,
    none_finite: str = "no starting point of the search gave a finite loss",
    reproject: bool = True,
) -> Search:
    """Best of ``starts``, refined over the nonlinear parameters with the gains profiled out (module docstring).

    ``project(x, start)``: the projection at transformed parameters ``x`` (``start``: the best start, for a caller
    whose model template is the start itself); ``x_of(start)``: a start's transformed parameters (1-D array).
    The starts' losses: ``losses`` (already evaluated, e.g. by `grid_losses`), else ``score(start)`` for each,
    else ``project(x_of(start), start).loss``; a single start with neither ``losses`` nor ``score`` is not scored
    (a refinement evaluates it anyway).  No finite start loss raises `UserInputError` (``none_finite``).
    ``refine``: `Bounded`, `NelderMead` or None; a start without parameters (``x`` of size 0) is not refined.
    ``reproject``: evaluate ``project`` once more at the chosen ``x`` (`Search.profiled`).
    """
    starts = list(starts)
    if not starts:
        raise ValueError("search needs at least one start")
    if losses is not None:
        start_losses = np.asarray(losses, dtype=np.float64)
        if start_losses.shape != (len(starts),):
            raise ValueError(f"got {start_losses.shape} losses for {len(starts)} starts")
    elif score is not None:
        start_losses = np.array([float(score(s)) for s in starts])
    elif len(starts) > 1:
        start_losses = np.array([float(project(np.asarray(x_of(s), dtype=np.float64), s).loss) for s in starts])
    else:
        start_losses = None
    if start_losses is not None and not np.any(np.isfinite(start_losses)):
        raise UserInputError(none_finite)
    best = 0 if start_losses is None else best_start(start_losses)
    start = starts[best]
    x = np.asarray(x_of(start), dtype=np.float64)
    seen = [Profiled(np.inf, None)]

    def evaluate(z):
        p = project(z, start)
        if p.loss < seen[0].loss:
            seen[0] = p
        return p.loss

    n_evals, converged, refined, n_runs = 0, True, False, 0
    if isinstance(refine, Bounded):
        if start_losses is None or x.size != 1:
            raise ValueError("Bounded refines one parameter from a scored grid of starts")
        if 0 < best < len(starts) - 1:
            from scipy.optimize import minimize_scalar

            res = minimize_scalar(
                lambda t: evaluate(np.array([t])),
                bounds=(x_of(starts[best - 1])[0], x_of(starts[best + 1])[0]),
                method="bounded",
                options={"xatol": refine.xatol},
            )
            n_evals, converged = int(res.nfev), bool(res.success)
            if res.fun <= start_losses[best]:
                x, refined = np.array([float(res.x)]), True
    elif isinstance(refine, NelderMead) and x.size > 0:
        from scipy.optimize import minimize

        steps = np.broadcast_to(np.asarray(refine.steps, dtype=np.float64), x.shape)
        options = {"xatol": refine.xatol, "fatol": refine.fatol}
        if refine.maxiter is not None:
            options["maxiter"] = int(refine.maxiter)
        if refine.maxfev is not None:
            options["maxfev"] = int(refine.maxfev)
        order = [best]
        if start_losses is not None and refine.n_starts > 1:
            ranked = np.argsort(np.where(np.isnan(start_losses), np.inf, start_losses), kind="stable")
            order = [int(i) for i in ranked[: int(refine.n_starts)] if np.isfinite(start_losses[i])]
        chosen = None  # (final loss, x, start index, converged)
        for run, i in enumerate(order):
            if run == 1 and refine.retry_if is not None and not refine.retry_if(chosen[1]):
                break  # the best start's simplex ended inside the search region: the runners-up are not needed
            start = starts[i]
            x0 = np.asarray(x_of(start), dtype=np.float64)
            cache = {}

            def objective(z, cache=cache):
                if refine.cache_decimals is None:
                    v = evaluate(z)
                    return v if np.isfinite(v) else refine.bad
                key = tuple(np.round(z, refine.cache_decimals))
                if key not in cache:
                    v = evaluate(z)
                    cache[key] = v if np.isfinite(v) else refine.bad
                return cache[key]

            simplex = [x0] + [x0 + np.eye(x0.size)[k] * steps[k] for k in range(x0.size)]
            res = minimize(objective, x0, method="Nelder-Mead", options={**options, "initial_simplex": np.array(simplex)})
            n_evals += len(cache) if refine.cache_decimals is not None else int(res.nfev)
            n_runs += 1
            if chosen is None or res.fun < chosen[0]:
                chosen = (res.fun, np.asarray(res.x, dtype=np.float64), i, bool(res.success))
        _, x, best, converged = chosen
        start, refined = starts[best], True
    elif refine is not None and not isinstance(refine, NelderMead):
        raise ValueError(f"refine must be Bounded, NelderMead or None, got {refine!r}")
    profiled = project(x, start) if reproject else None
    return Search(x, profiled, seen[0], best, start_losses, n_evals, converged, refined, n_runs)
