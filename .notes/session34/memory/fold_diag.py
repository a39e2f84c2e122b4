"""Session 34: one leave-one-record-out fold with and without the per-record operator memory: held-out error, gains,
and which training operators are wiped by their own record (their start forgotten before the record ends).

    python .notes/session34/memory/fold_diag.py SEED SET HELD_OUT_INDEX      (records from fit_sets.py in /tmp/pm_recs)
"""

import sys
from pathlib import Path

import jax.numpy as jnp
import numpy as np

import smafl_jax as sj
from smafl_jax.identify import _record_starts as rs  # private: switch the memory step
from smafl_jax.identify._multi_record import _heldout  # private: the held-out rule of fit_records
from smafl_jax.models._hysteresis import hysteresis_of, record_model  # private: per-record model

seed, name, held = int(sys.argv[1]), sys.argv[2], int(sys.argv[3])
d = Path(f"/tmp/pm_recs/{seed}_{name}")
paths = sorted(d.glob("*.csv"))
recs = [sj.load_record(p) for p in paths]
noise = float((d / "noise_0.txt").read_text())
train = [r for i, r in enumerate(recs) if i != held]
for flag in (False, True):
    rs.RECORD_MEMORY = flag
    saved, doc, details = sj.fit_records(train, model="cascade", split="none")
    rm = details["record_model"]
    y, scored, start = _heldout(saved, {}, recs[held])
    err = np.sqrt(np.mean((y[scored] - recs[held].y[scored]) ** 2)) / noise
    h = hysteresis_of(rm)
    print(f"memory {flag}: held-out {paths[held].name} {err:.2f}x, train {doc['metrics']['train']['rmse'] / noise:.2f}x, "
          f"k1 {float(rm.thermal.k1):.4g}, u0 {np.round(np.asarray(rm.thermal.u0), 3)}, start {start.get('thermal')} {start.get('memory')}")
    print("  gains v", np.round(np.asarray(h.v), 3), "w", np.round(np.asarray(h.w).ravel(), 3), "gain", float(h.gain),
          "poly", np.round(np.asarray(h.poly), 3), "offset", float(h.offset))
    if rm.record_memory is not None:
        for i, r in enumerate(train):
            m = record_model(rm, i)
            x = m.hysteresis_input(jnp.asarray(r.u), r.dt)
            _, C = m.hysteresis.memory_columns(x, np.vstack([np.zeros(h.n_operators), np.ones(h.n_operators)]))
            C = np.asarray(C)
            wiped = np.abs(C[0, -1] - C[1, -1]) < 1e-9
            frac = 1 / (1 + np.exp(-np.asarray(rm.record_memory[i])))
            print(f"  record {i}: wiped {wiped.sum()}/{wiped.size}; fractions of unwiped operators with gain > 0:",
                  [(j, round(float(frac[j]), 2)) for j in np.flatnonzero(~wiped) if np.concatenate([np.asarray(h.v), np.asarray(h.w).ravel()])[j] > 1e-6])
