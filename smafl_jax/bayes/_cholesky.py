"""Cholesky factorisation and triangular solves of small SPD systems in plain XLA operations.

Why not `jnp.linalg.cholesky` / `jax.scipy.linalg.solve_triangular`: on the CPU those are LAPACK custom calls
that, batched under `vmap`, fan their batch out into XLA's intra-op thread pool from a thread of that same pool
and wait for it.  With every pool thread inside such a call nothing is left to run the work: `smafl sample`'s
predictive stage hung for good (zero CPU, native stacks in ``lapack_dtrsm_ffi -> ParallelBatchMap ->
BlockingCounter::Wait`` on both pool threads) on 4 of 4 resumed chains of a session-36 new-user trial (jaxlib
0.10.2, 2 cores; `XLA_FLAGS=--xla_cpu_multi_thread_eigen=false` did not help).  The posterior's gain systems are
small (p = the number of linear weights, ~30 for the default EUPI), so a column-by-column factorisation in a
`lax.fori_loop` costs little next to the model simulation, and it is ordinary XLA code: batched by `vmap`, run by
whichever thread has it, never re-entering the pool.

A matrix that is not positive definite gives NaN (a square root of a negative pivot), as LAPACK's gives NaN in JAX.
"""

from __future__ import annotations

import jax.numpy as jnp
from jax import lax

__all__ = ["cholesky", "solve_lower", "solve_lower_transpose", "cho_solve"]


def cholesky(m: jnp.ndarray) -> jnp.ndarray:
    """Lower-triangular ``L`` with ``L @ L.T == m`` for a symmetric positive definite ``m`` (p, p)."""
    p = m.shape[-1]
    idx = jnp.arange(p)

    def column(j, low):
        row_j = jnp.where(idx < j, low[j], 0.0)  # L[j, :j]; columns >= j of ``low`` are still zero
        s = m[:, j] - low @ row_j  # m[i, j] - sum_{k<j} L[i, k] L[j, k], for every i
        d = jnp.sqrt(s[j])
        return low.at[:, j].set(jnp.where(idx > j, s / d, jnp.where(idx == j, d, 0.0)))

    return lax.fori_loop(0, p, column, jnp.zeros_like(m))


def solve_lower(low: jnp.ndarray, b: jnp.ndarray) -> jnp.ndarray:
    """``x`` with ``low @ x == b`` (forward substitution; ``low`` lower triangular, ``b`` a vector)."""

    def step(i, x):
        return x.at[i].set((b[i] - low[i] @ x) / low[i, i])  # x[i:] is still zero

    return lax.fori_loop(0, b.shape[0], step, jnp.zeros_like(b))


def solve_lower_transpose(low: jnp.ndarray, z: jnp.ndarray) -> jnp.ndarray:
    """``x`` with ``low.T @ x == z`` (back substitution)."""
    p = z.shape[0]

    def step(k, x):
        i = p - 1 - k
        return x.at[i].set((z[i] - low[:, i] @ x) / low[i, i])  # x[:i + 1] is still zero

    return lax.fori_loop(0, p, step, jnp.zeros_like(z))


def cho_solve(low: jnp.ndarray, b: jnp.ndarray) -> jnp.ndarray:
    """``x`` with ``(low @ low.T) @ x == b``."""
    return solve_lower_transpose(low, solve_lower(low, b))
