"""Per-record thermal starts of a joint fit: each of several records starts from its own thermal state.

Why: records of one rig rarely start alike (one cold with the power on, one warm after an earlier run).  With one
start rule for all of them the joint fit misfits the start of the odd record and bends the thermal rate to absorb it;
measured on one independent plant (session 32, PWM 25 Hz cold + multisine 100 Hz warm): training 3.41x the noise,
leave-one-record-out 12.4x, time constant 131 s instead of 21 s, against 1.01x / 2.1x when both start cold.

How: each record's initial effective voltage ``u0`` (`JouleThermal.with_record_starts`: the state a constant ``u0`` V
would hold) is one of the screening's start candidates (`START_FRACTIONS` of the input maximum, the record's own first
sample, the start the shared rule gives it), chosen jointly with the thermal rate on a grid: for every record, start
candidate and rate on the grid the record's normal equations are formed once (one vmapped design per record and
candidate), so a combination of starts costs one small bounded least-squares solve of summed normal equations
(`linear.solve_gram`).  At each rate the starts are chosen record by record until none moves, from the shared rule's
starts and from all-cold starts; the best (rate, starts) is then profiled in the rate (`init_profile`) and the joint
refinement trains the starts with everything else.  Why a grid in the rate: a start mismatch bends the rate (the warm
pair above), and at the bent rate a record-by-record search stays with the shared rule's starts (measured: a cold,
cold, warm set screened at a time constant of 600 s kept inverted starts; the plant's was 10 s).
"""

from __future__ import annotations

from typing import Any

import jax.numpy as jnp
import numpy as np

from .._progress import say as progress_line
from ..models._hysteresis import hysteresis_of, thermal_of
from . import varpro
from ._choose import COLD_FRACTION, SCREEN_XATOL, START_FRACTIONS
from ._fit import _as_weights, _default_k1_grid, _linear_part, _set_k1, as_fit_data, init_profile
from .linear import solve_gram

__all__ = ["fit_record_starts", "RECORD_K1_GRID", "RECORD_SWEEPS"]

#: Thermal rates of the grid the starts are chosen on (log-spaced over the fit's k1 range; the model's own is added).
RECORD_K1_GRID = 8
#: Record-by-record passes over the starts at one rate (stops earlier when no start moves).
RECORD_SWEEPS = 4
#: Design blocks of one vmapped call stay under this many bytes (as `init_profile`'s chunks).
_CHUNK_BYTES = 64 << 20


def _normal_equations(model, feats, rec, w, starts, k1s):
    """``(G (C, K, p, p), h (C, K, p), bb)``: the weighted normal equations of one record for every start
    ``starts[c] = (u0, memory rule or None)`` and rate ``k1s[k]``."""
    u, y, d = rec
    keep = w > 0
    sw = np.sqrt(w[keep])
    b = y[keep] * sw
    n_cols = int(np.shape(feats(model.for_record(0), jnp.zeros(3), jnp.asarray(1.0)))[1])
    chunk = int(max(1, min(len(k1s), _CHUNK_BYTES // (8 * u.shape[0] * n_cols))))
    G = np.empty((len(starts), len(k1s), n_cols, n_cols))
    h = np.empty((len(starts), len(k1s), n_cols))
    for c, (u0, rule) in enumerate(starts):
        start = model.with_record_starts([u0], None if rule is None else [rule]).for_record(0)
        for k0 in range(0, len(k1s), chunk):
            ks = k1s[k0 : k0 + chunk]
            A = np.asarray(varpro.batch_design(feats, _set_k1, start, jnp.asarray(ks), jnp.asarray(u), jnp.asarray(d)))
            A = A[:, keep, :] * sw[None, :, None]
            At = A.transpose(0, 2, 1)  # batched BLAS products (einsum's loops took most of the search on 300 relays)
            G[c, k0 : k0 + len(ks)] = At @ A
            h[c, k0 : k0 + len(ks)] = At @ b
    return G, h, float(b @ b)


def _gram_loss(eqs, k, choice, nonneg) -> float:
    """Profiled loss (0.5 x weighted SSE) at rate index ``k`` with record ``i`` started at its candidate ``choice[i]``."""
    if not all(np.all(np.isfinite(e[0][c, k])) and np.all(np.isfinite(e[1][c, k])) for e, c in zip(eqs, choice)):
        return np.inf
    G = sum(e[0][c, k] for e, c in zip(eqs, choice))
    h = sum(e[1][c, k] for e, c in zip(eqs, choice))
    return solve_gram(G, h, sum(e[2] for e in eqs), nonneg).loss


def _choose_starts(eqs, k, first, nonneg):
    """Record-by-record descent over the start candidates at rate index ``k`` from the choice ``first``:
    ``(loss, choice)``."""
    choice = list(first)
    loss = _gram_loss(eqs, k, choice, nonneg)
    for _ in range(RECORD_SWEEPS):
        moved = False
        for i, (G, _, _) in enumerate(eqs):
            for c in range(G.shape[0]):
                if c == choice[i]:
                    continue
                trial = choice[:i] + [c] + choice[i + 1 :]
                got = _gram_loss(eqs, k, trial, nonneg)
                if got < loss * (1.0 - 1e-9):
                    loss, choice, moved = got, trial, True
        if not moved:
            break
    return loss, choice


def _record_rules(model, feats, data, weights, candidates, starts, k1, nonneg):
    """Each record's operator-memory rule (`AbstractHysteresis.RULE_INITS`) with its start, chosen record by record at
    rate ``k1`` over (start candidate x rule); None when the hysteresis has one rule or a fitted memory.  Why: a record
    that starts warm came up from cold, so its operators sit on another branch than those of a record at rest."""
    h = hysteresis_of(model)
    rules = tuple(h.RULE_INITS)
    if h.init not in rules or len(rules) < 2:
        return None
    pairs = [[(u0, r) for u0 in cands for r in rules] for cands in candidates]
    eqs = [_normal_equations(model, feats, rec, w, p, np.array([k1])) for rec, w, p in zip(data, weights, pairs)]
    first = [p.index((s, h.init)) for p, s in zip(pairs, starts)]
    _, choice = _choose_starts(eqs, 0, first, nonneg)
    chosen = [p[c] for p, c in zip(pairs, choice)]
    starts[:] = [u0 for u0, _ in chosen]
    return tuple(r for _, r in chosen)


def fit_record_starts(model: Any, data: Any, weights: Any = None, *, progress: bool = False) -> tuple[Any, dict] | None:
    """``(model, info)``: ``model`` (a profiled cascade with one start rule) with one thermal start per record, the gains
    and thermal rate profiled at those starts; None for one record or a model without a thermal stage.

    ``info``: the shared rule, the starts per record (V) under it and as chosen, the profiled losses before and after.
    """
    data = as_fit_data(data)
    weights = _as_weights(weights, data)
    th = thermal_of(model)
    part = _linear_part(model)
    if th is None or part is None or len(data) < 2 or th.n_record_starts is not None:
        return None
    feats, nonneg, _ = part
    say = progress_line if progress else (lambda msg: None)
    u_hi = max(float(np.max(u)) for u, _, _ in data)
    if not u_hi > 0:
        return None
    floor = COLD_FRACTION * u_hi  # a start at exactly 0 V could never warm up in the refinement (softplus, `COLD_FRACTION`)
    before = [max(th.start_voltage(u[0]), floor) for u, _, _ in data]
    candidates = [
        sorted({*(f * u_hi for f in START_FRACTIONS), max(float(u[0]), floor), b}) for (u, _, _), b in zip(data, before)
    ]
    k1s = np.unique(np.concatenate([_default_k1_grid(data, RECORD_K1_GRID), [float(th.k1)]]))
    eqs = [
        _normal_equations(model, feats, rec, w, [(c, None) for c in cands], k1s)
        for rec, w, cands in zip(data, weights, candidates)
    ]
    shared = [cands.index(b) for cands, b in zip(candidates, before)]
    cold = [0] * len(data)  # the lowest candidate of each record: COLD_FRACTION of the input maximum
    k_own = int(np.flatnonzero(k1s == float(th.k1))[0])
    loss0 = _gram_loss(eqs, k_own, shared, nonneg)
    best = (np.inf, None, None)
    for k in range(k1s.size):
        for first in (shared, cold):
            loss, choice = _choose_starts(eqs, k, first, nonneg)
            if loss < best[0]:
                best = (loss, k, choice)
    if best[1] is None:
        return None
    _, k, choice = best
    starts = [cands[c] for cands, c in zip(candidates, choice)]
    rules = _record_rules(model, feats, data, weights, candidates, starts, k1s[k], nonneg)
    # the rate between the chosen grid point's neighbours, gains profiled (the fit's own initialiser)
    at = _set_k1(model.with_record_starts(starts, rules), k1s[k])
    m, prof = init_profile(at, data, weights=weights, k1_grid=k1s[max(k - 1, 0) : k + 2], xatol=SCREEN_XATOL)
    say(
        "  per-record thermal starts: "
        + ", ".join(f"{a:.3g} -> {b:.3g} V" for a, b in zip(before, starts))
        + f" (profiled loss {loss0:.6g} -> {prof['loss']:.6g}, k1 {float(th.k1):.4g} -> {float(m.thermal.k1):.4g} 1/s)"
    )
    info = {
        "rule": "one initial effective voltage per record, chosen with the thermal rate on a grid (gains profiled), "
        "then trained with the rest",
        "shared_rule": [
            th.init,
            None if th.u0 is None else float(th.u0),
        ],  # the one rule it came from (`JouleThermal.start_voltage`)
        "shared_u0": before,
        "u0": starts,
        "memory": list(rules) if rules else None,
        "profiled_loss_shared": loss0,
        "profiled_loss": float(prof["loss"]),
    }
    return m, info
