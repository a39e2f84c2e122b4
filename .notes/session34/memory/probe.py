"""Session 34 oracle probe: would a per-record, per-operator memory search pay in a joint fit of several records?

For each set (experiments/several_records.py SETS, same records), fit jointly as the CLI does (`fit_records`,
``--model cascade --split none``), take the fitted per-record model (`details["record_model"]`), then, holding the
thermal parameters, per-record u0 and thresholds/tilts fixed, search every record's operator start positions one
operator at a time over a grid of fractions, the gains SHARED across records and profiled by `linear.solve_gram` on the
summed normal equations.  Reported per record: training RMSE / noise SD as fitted (LM, gain prior), re-profiled (the
same memory, gains by BVLS: the search's baseline) and after the search.

    python .notes/session34/memory/probe.py OUT.json SEED [SEED ...]
"""

from __future__ import annotations

import json
import os
import pickle
import sys
import time
from pathlib import Path

import jax.numpy as jnp
import numpy as np

ROOT = Path(__file__).resolve().parents[3]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

import indep_plant  # noqa: E402

import smafl_jax as sj  # noqa: E402
from smafl_jax.identify._fit import _features, _linear_part  # noqa: E402  private: the fit's design
from smafl_jax.identify.linear import solve_gram  # noqa: E402
from smafl_jax.models._hysteresis import hysteresis_of, record_model  # noqa: E402  private: per-record model

SETS = {
    "mixed starts": [("pwm", 25, 8, "cold"), ("multisine", 25, 8, "warm"), ("steps", 10, 12, "mid")],
    "warm + cold": [("pwm", 25, 8, "cold"), ("multisine", 50, 5, "warm")],
}
FRACTIONS = np.linspace(0.0, 1.0, 11)
SWEEPS = 3


def joint_memory_search(model, data, fractions=FRACTIONS, sweeps=SWEEPS):
    """Per record, per operator start fractions, gains shared and profiled on the summed normal equations.
    Returns (losses per record before/after under the profiled gains, total loss before, after, chosen fractions)."""
    feats, nonneg, _ = _linear_part(model)
    blocks = []
    for i, (u, y, d) in enumerate(data):
        m = record_model(model, i)
        h = hysteresis_of(m)
        x = m.hysteresis_input(jnp.asarray(u), d)
        A = np.asarray(_features(feats, m, jnp.asarray(u), jnp.asarray(d)), dtype=np.float64)
        cols, C = h.memory_columns(x, np.broadcast_to(fractions[:, None], (fractions.size, h.n_operators)))
        C = np.asarray(C, dtype=np.float64)  # (K, T, n_ops)
        blocks.append({"A": A.copy(), "C": C, "b": np.asarray(y, np.float64), "cols": np.asarray(cols), "choice": -np.ones(h.n_operators, int)})
    G = sum(bk["A"].T @ bk["A"] for bk in blocks)
    hb = sum(bk["A"].T @ bk["b"] for bk in blocks)
    bb = sum(float(bk["b"] @ bk["b"]) for bk in blocks)
    sol0 = solve_gram(G, hb, bb, nonneg)
    best = sol0.loss
    for _ in range(sweeps):
        moved = False
        for bk in blocks:
            A, C, b = bk["A"], bk["C"], bk["b"]
            for i, j in enumerate(bk["cols"]):
                old = A[:, j].copy()
                old_cross, old_cb = old @ A, old @ b
                X = C[:, :, i]  # (K, T)
                cross = X @ A  # (K, p): column j of A is still the old one here
                cc = np.einsum("kt,kt->k", X, X)
                cb = X @ b
                trial, k_best = best, None
                for k in range(X.shape[0]):
                    Gk, hk = G.copy(), hb.copy()
                    row = G[j, :] - old_cross + cross[k]
                    row[j] = G[j, j] - old @ old + cc[k]
                    Gk[j, :] = row
                    Gk[:, j] = row
                    hk[j] = hb[j] - old_cb + cb[k]
                    loss = solve_gram(Gk, hk, bb, nonneg).loss
                    if loss < trial * (1.0 - 1e-9):
                        trial, k_best = loss, k
                if k_best is not None:
                    row = G[j, :] - old_cross + cross[k_best]
                    row[j] = G[j, j] - old @ old + cc[k_best]
                    G[j, :] = row
                    G[:, j] = row
                    hb[j] = hb[j] - old_cb + cb[k_best]
                    A[:, j] = X[k_best]
                    bk["choice"][i] = k_best
                    best, moved = trial, True
        if not moved:
            break
    sol = solve_gram(G, hb, bb, nonneg)
    return sol0, sol, blocks, best


def run(seed, name, spec, out_dir):
    out_dir.mkdir(parents=True, exist_ok=True)
    recs, truths = [], []
    for j, (drive, rate, minutes, start) in enumerate(spec):
        rec = indep_plant.make_record(seed, drive=drive, rate_hz=rate, minutes=minutes, start=start)
        path = out_dir / f"s{seed}_{j}_{drive}{rate}_{start}.csv"
        indep_plant.write_csv(path, rec)
        recs.append(sj.load_record(path))
        truths.append(rec)
    noise = float(truths[0]["noise_sd"])
    cache = out_dir / "fit.pkl"
    if cache.exists():  # the joint fit of an earlier run of the probe on the same records
        with open(cache, "rb") as fh:
            doc, model, t_fit = pickle.load(fh)
    else:
        t0 = time.perf_counter()
        _, doc, details = sj.fit_records(recs, model="cascade", split="none")
        t_fit = time.perf_counter() - t0
        model = details["record_model"]
        with open(cache, "wb") as fh:
            pickle.dump((doc, model, t_fit), fh)
    data = [(r.u, r.y, r.dt) for r in recs]
    fitted = [float(np.sqrt(np.mean((np.asarray(record_model(model, i).simulate(jnp.asarray(u), d)) - y) ** 2))) for i, (u, y, d) in enumerate(data)]
    # the design blocks before any move: the re-profiled baseline
    feats, nonneg, _ = _linear_part(model)
    A0 = [np.asarray(_features(feats, record_model(model, i), jnp.asarray(u), jnp.asarray(d))) for i, (u, _, d) in enumerate(data)]
    t1 = time.perf_counter()
    sol0, sol, blocks, _ = joint_memory_search(model, data)
    t_search = time.perf_counter() - t1
    prof = [float(np.sqrt(np.mean((A @ sol0.x - y) ** 2))) for A, (_, y, _) in zip(A0, data)]
    after = [float(np.sqrt(np.mean((bk["A"] @ sol.x - bk["b"]) ** 2))) for bk in blocks]
    # what a per-record search with per-record gains could reach (an upper bound on the memory's worth: each record alone)
    row = {
        "seed": seed,
        "set": name,
        "records": [f"{d}{r} {s}" for d, r, _, s in spec],
        "noise_sd": noise,
        "memory": [p.get("memory") for p in (doc.get("per_record_start") or [{}] * len(spec))],
        "u0": [p.get("u0_V") for p in (doc.get("per_record_start") or [{}] * len(spec))],
        "fitted_x_noise": [v / noise for v in fitted],
        "reprofiled_x_noise": [v / noise for v in prof],
        "searched_x_noise": [v / noise for v in after],
        "moved_operators": [int(np.sum(bk["choice"] >= 0)) for bk in blocks],
        "n_operators": int(blocks[0]["choice"].size),
        "fit_s": t_fit,
        "search_s": t_search,
        "tau_fit": 1.0 / float(model.thermal.k1),
        "tau_plant": 1.0 / truths[0]["truth"]["thermal"]["k1"],
        "plant_memory_kind": truths[0]["truth"]["hysteresis"]["memory"]["kind"],
    }
    return row


def main():
    out = Path(sys.argv[1])
    seeds = [int(s) for s in sys.argv[2:]]
    rows = json.loads(out.read_text()) if out.exists() else []
    done = {(r["seed"], r["set"]) for r in rows}
    for seed in seeds:
        for name, spec in SETS.items():
            if (seed, name) in done:
                continue
            row = run(seed, name, spec, Path(f"/tmp/pm_{seed}_{name.replace(' ', '').replace('+', '_')}"))
            rows.append(row)
            tmp = out.with_suffix(".tmp")
            tmp.write_text(json.dumps(rows, indent=1))
            os.replace(tmp, out)
            f = lambda xs: ", ".join(f"{v:.2f}" for v in xs)
            print(
                f"seed {seed} {name}: memory {row['memory']}, fitted {f(row['fitted_x_noise'])}, re-profiled "
                f"{f(row['reprofiled_x_noise'])}, searched {f(row['searched_x_noise'])} (moved {row['moved_operators']} of "
                f"{row['n_operators']}; fit {row['fit_s']:.0f} s, search {row['search_s']:.0f} s)",
                flush=True,
            )


if __name__ == "__main__":
    main()
