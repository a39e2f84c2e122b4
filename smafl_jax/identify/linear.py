"""Bounded, non-negative and ridge linear least squares: the one linear solver of fit, diagnose and Preisach CV.

Every identification in the toolkit has linear gains (EUPI / Preisach weights,
offsets, linear effect fields) that enter the output linearly once the
nonlinear parameters are fixed; `solve` finds them.  It minimises

    0.5 |A x - b|^2 + 0.5 ridge n |s * x|^2 + 0.5 x' P x
    subject to lower <= x <= upper   (``nonneg`` columns: x >= 0)

with ``n`` the number of rows, ``s`` the column RMS (`column_scale`) and
``P`` an optional penalty matrix (e.g. Preisach smoothness).  ``ridge`` is
relative to the diagonal of the column-scaled Gram matrix (each entry ``n``):
it is dimensionless and the same for any record length and any column unit,
so a cross-validated value carries over (issue 18).

How (reasons):

- Columns are scaled to unit RMS first: operator columns span many orders of
  magnitude and BVLS / NNLS are not scale invariant in floating point.
- A tall problem is reduced to ``p x p`` (``|A x - b|^2 = |R z - c|^2 + const``,
  ``R' R = G``, ``R' c = A' b``) through a Cholesky factor of the Gram matrix
  (plus ridge and penalty), so the active-set iterations are cheap (a LAPACK QR
  of the tall matrix was 20-40x slower on a loaded 2-core machine).  A small
  diagonal ``jitter`` (relative to the mean diagonal of the data Gram matrix)
  keeps collinear operator columns from breaking the factorisation.
- ``method="bvls"``: scipy ``lsq_linear(method="bvls")`` (any bounds).
  ``method="nnls"``: Lawson-Hanson NNLS with each unbounded column entered twice
  (``x = x+ - x-``); the same minimiser, about 25x faster on a 631-relay
  Preisach grid (only ``nonneg`` / unbounded columns).
- ``drop_constant``: non-negative columns the data never moved (an operator
  whose threshold lies above the trained input range) are collinear with the
  offset; any gain on them is arbitrary and bites the first time a later input
  exceeds the trained range, so they get gain 0.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import scipy.linalg
from scipy.optimize import lsq_linear, nnls

__all__ = ["LinearSolution", "solve", "solve_gram", "column_scale", "METHODS"]

METHODS = ("bvls", "nnls")
SCALE_FLOOR = 1e-12  # columns with RMS below this are treated as having RMS 1e-12 (all-zero columns)
DEAD_RTOL = 1e-9  # a column whose peak-to-peak is below DEAD_RTOL x max|A| never moved


@dataclasses.dataclass(frozen=True)
class LinearSolution:
    """``x`` the coefficients; ``loss = 0.5 |A x - b|^2`` (data term only); ``dof`` the effective number of
    parameters (trace of the hat matrix over the free columns) when asked for, else None."""

    x: np.ndarray
    loss: float
    dof: float | None = None


def column_scale(A: np.ndarray, scale: bool = True) -> np.ndarray:
    """Column RMS of ``A`` (floored at 1e-12), or ones when ``scale`` is False."""
    if not scale:
        return np.ones(A.shape[1])
    return np.maximum(np.sqrt(np.mean(A**2, axis=0)), SCALE_FLOOR)


def _bounds(p, nonneg, lower, upper):
    nonneg = np.zeros(p, bool) if nonneg is None else np.broadcast_to(np.asarray(nonneg, bool), (p,)).copy()
    lb = np.where(nonneg, 0.0, -np.inf)
    ub = np.full(p, np.inf)
    if lower is not None:
        lb = np.maximum(lb, np.broadcast_to(np.asarray(lower, float), (p,)))
    if upper is not None:
        ub = np.broadcast_to(np.asarray(upper, float), (p,)).astype(float)
    if np.any(lb > ub):
        raise ValueError(f"lower bound above upper bound in columns {np.flatnonzero(lb > ub).tolist()}")
    return nonneg, lb, ub


def solve(
    A,
    b,
    nonneg=None,
    *,
    lower=None,
    upper=None,
    ridge: float = 0.0,
    penalty=None,
    scale: bool = True,
    jitter: float = 1e-12,
    method: str = "bvls",
    drop_constant: bool = False,
    dead_rtol: float = DEAD_RTOL,
    clip: bool = True,
    dof: bool = False,
    rhs: str = "lower",
    jitter_of: str = "mean",
) -> LinearSolution:
    """Bounded / non-negative / ridge least squares (module docstring); ``A`` (n, p), ``b`` (n,).

    ``nonneg``: bool per column (x >= 0); ``lower`` / ``upper``: further bounds (bvls only);
    ``ridge``: penalty on the column-scaled coefficients, relative to the scaled Gram diagonal;
    ``penalty``: a (p, p) positive semi-definite matrix on the unscaled coefficients;
    ``scale``: scale columns to unit RMS; ``jitter``: diagonal added to the reduced Gram matrix,
    relative to its mean diagonal; ``clip``: put bounded results that BVLS leaves a rounding error
    outside their bound back on it (a saved model with a weight of -1e-18 is refused on loading);
    ``dead_rtol``: with ``drop_constant``, a non-negative column whose peak-to-peak is at most ``dead_rtol`` x max|A|
    gets coefficient 0 (default `DEAD_RTOL`: it never moved);
    ``dof``: also return the effective number of parameters; ``rhs``: how ``R' c = A' b`` is solved,
    ``"lower"`` (forward substitution on ``R'``) or ``"transpose"`` (LAPACK's transposed solve on ``R``):
    the same mathematics, rounded differently in the last bit; ``jitter_of``: ``"mean"`` (jitter x the
    mean diagonal, independent of the number of columns) or ``"trace"`` (jitter x the trace).
    `smafl_jax.identify._fit` uses ``rhs="transpose", jitter_of="trace"`` so that its fits reproduce their
    earlier numbers exactly.
    """
    A = np.asarray(A, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    if A.ndim != 2 or b.shape != (A.shape[0],):
        raise ValueError(f"A must be (n, p) and b (n,), got {A.shape} and {b.shape}")
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}; choose one of {METHODS}")
    if rhs not in ("lower", "transpose"):
        raise ValueError(f"rhs must be 'lower' or 'transpose', got {rhs!r}")
    if jitter_of not in ("mean", "trace"):
        raise ValueError(f"jitter_of must be 'mean' or 'trace', got {jitter_of!r}")
    if not ridge >= 0.0:
        raise ValueError(f"ridge must be >= 0, got {ridge!r}")
    p = A.shape[1]
    nonneg, lb, ub = _bounds(p, nonneg, lower, upper)
    if method == "nnls" and (lower is not None or upper is not None):
        raise ValueError("method='nnls' handles non-negative and unbounded columns only; use method='bvls' for bounds")
    if drop_constant:
        # the peak-to-peak of a column-major copy: numpy reduces a row-major (n, p) array over its rows one short row
        # at a time (3x the time of the copy and the contiguous reduction); max and min are exact either way
        spread = np.ptp(np.asfortranarray(A), axis=0)
        dead = nonneg & (spread <= dead_rtol * max(float(np.max(np.abs(A))), 1e-300))
        if np.any(dead):
            keep = ~dead
            if not np.any(keep):
                return LinearSolution(np.zeros(p), 0.5 * float(b @ b), 0.0 if dof else None)
            P = None if penalty is None else np.asarray(penalty, float)[np.ix_(keep, keep)]
            sub = solve(
                A[:, keep],
                b,
                nonneg[keep],
                lower=None if lower is None else lb[keep],
                upper=None if upper is None else ub[keep],
                ridge=ridge,
                penalty=P,
                scale=scale,
                jitter=jitter,
                method=method,
                drop_constant=True,
                dead_rtol=dead_rtol,
                clip=clip,
                dof=dof,
                rhs=rhs,
                jitter_of=jitter_of,
            )
            x = np.zeros(p)
            x[keep] = sub.x
            return LinearSolution(x, sub.loss, sub.dof)
    s = column_scale(A, scale)
    As = A / s if scale else A
    Ps = None
    if penalty is not None:
        Ps = np.asarray(penalty, float)
        if scale:
            Ps = Ps / np.outer(s, s)  # x' P x = z' (P / s s') z with z = s x
    n = A.shape[0]
    G0 = As.T @ As
    extra = np.zeros(p) if ridge == 0.0 else np.full(p, ridge * n)
    jit = jitter * np.trace(G0) if jitter_of == "trace" else jitter * max(np.trace(G0) / p, 1e-300)
    R, c = As, b
    if n > p or Ps is not None or ridge > 0.0:
        G = G0 + Ps if Ps is not None else G0.copy()
        if ridge > 0.0:
            G[np.diag_indices_from(G)] += extra
        G[np.diag_indices_from(G)] += jit
        try:
            if rhs == "lower":
                R = np.triu(scipy.linalg.cho_factor(G, lower=False)[0])
                c = scipy.linalg.solve_triangular(R.T, As.T @ b, lower=True)
            else:  # a Fortran-ordered factor: LAPACK solves with R transposed in place
                R = scipy.linalg.cholesky(G, lower=False)
                c = scipy.linalg.solve_triangular(R, As.T @ b, trans="T")
        except np.linalg.LinAlgError:
            if Ps is not None:
                raise
            # not positive definite even with the jitter: the full system, ridge as extra rows
            R, c = As, b
            if ridge > 0.0:
                R, c = np.vstack([As, np.sqrt(ridge * n) * np.eye(p)]), np.concatenate([b, np.zeros(p)])
    if method == "bvls":
        z = lsq_linear(R, c, bounds=(lb * s, ub * s), method="bvls").x
        x = z / s
    else:
        free = ~nonneg
        z, _ = nnls(np.column_stack([R, -R[:, free]]), c, maxiter=50 * (p + int(free.sum())))
        x = z[:p].copy()
        x[free] -= z[p:]
        x = x / s
    if clip:
        x = np.clip(x, lb, ub)
    r = A @ x - b
    out_dof = None
    if dof:
        keep = ~nonneg | (x > 1e-10 * max(np.max(np.abs(x)), 1e-300))
        Af = As[:, keep]
        Gf0 = Af.T @ Af
        Gf = Gf0 + Ps[np.ix_(keep, keep)] if Ps is not None else Gf0.copy()
        if ridge > 0.0:
            Gf[np.diag_indices_from(Gf)] += extra[keep]
        Gf[np.diag_indices_from(Gf)] += jit
        out_dof = float(np.trace(np.linalg.solve(Gf, Gf0)))
    return LinearSolution(x, 0.5 * float(r @ r), out_dof)


def solve_gram(G, h, bb: float, nonneg=None, *, jitter: float = 1e-12) -> LinearSolution:
    """`solve` (BVLS, column-scaled, non-negative columns) from the normal equations: ``G = A' A``, ``h = A' b``,
    ``bb = b' b``; ``loss`` is ``0.5 |A x - b|^2``.

    Why: a search that swaps one column of ``A`` at a time (`smafl_jax.identify.search_memory`) updates one row and
    column of ``G`` instead of forming ``A' A`` again (``p x p`` work per trial instead of ``n p^2``).
    """
    G = np.asarray(G, dtype=np.float64)
    h = np.asarray(h, dtype=np.float64)
    p = G.shape[0]
    if G.shape != (p, p) or h.shape != (p,):
        raise ValueError(f"G must be (p, p) and h (p,), got {G.shape} and {h.shape}")
    nonneg, lb, ub = _bounds(p, nonneg, None, None)
    s = np.maximum(np.sqrt(np.maximum(np.diag(G), 0.0)), SCALE_FLOOR)
    Gs = G / np.outer(s, s)
    hs = h / s
    floor = jitter * max(float(np.trace(Gs)) / p, 1e-300)
    Gj = Gs.copy()
    Gj[np.diag_indices_from(Gj)] += floor
    try:
        R = scipy.linalg.cholesky(Gj, lower=False)
        c = scipy.linalg.solve_triangular(R, hs, trans="T")
    except np.linalg.LinAlgError:
        # Rounding made G indefinite beyond the jitter (columns equal up to rounding, e.g. two operators given the
        # same start, accumulated over a few hundred thousand samples): a square root from the eigen-decomposition
        # with the eigenvalues floored, the same quadratic form on the numerically positive part.
        ev, V = np.linalg.eigh(0.5 * (Gs + Gs.T))
        ev = np.maximum(ev, floor)
        R = np.sqrt(ev)[:, None] * V.T
        c = (V.T @ hs) / np.sqrt(ev)
    z = lsq_linear(R, c, bounds=(lb * s, ub * s), method="bvls").x
    x = np.clip(z / s, lb, ub)
    zs = x * s
    return LinearSolution(x, max(0.5 * float(bb - 2.0 * zs @ hs + zs @ Gs @ zs), 0.0))
