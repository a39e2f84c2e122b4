"""Discrete Preisach model vs EUPI on the SMA FORC record: outer 3-fold branch CV, inner CV on training branches (issue 6).

Run:  OPENBLAS_NUM_THREADS=1 python experiments/forc_preisach_cv.py [--data ../shared/data/real]
      [--out experiments/results/forc_preisach_cv.json]
Outer folds: branches with label % 3 == r held out (r = 0, 1, 2; branch 0, the major loop, always trains),
as `smafl_jax._diagnose.make_split`.  Per fold:
  - base EUPI and EUPI + output_saturation: the diagnosis' VarPro fits (fixed default grids, no tuning);
  - Preisach: (n_levels, lam) chosen by leave-one-branch-out CV over the outer-training FORCs only
    (`cv_fit_preisach`, criterion pooled inner RMSE), refitted on all outer-training branches.
Held-out e_r (eq. 3) and RMSE are reported; the held-out branches never enter any choice.
Data are read in place (source: /work/shared/data/real).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def _heldout(model, split):
    from smafl_jax import metrics

    y = np.concatenate([s.y for s in split.test])
    yh = np.concatenate([np.asarray(model.simulate(s.u, s.dt)) for s in split.test])
    return metrics(y, yh)


def main(argv=None):
    from smafl_jax import atomic_write_json, load_record
    from smafl_jax._diagnose import _metrics_pair, choose_base, fit_extended, make_split, n_parameters
    from smafl_jax._effects import ExtendedModel
    from smafl_jax._preisach import LAM_GRID, N_LEVELS_GRID, cv_fit_preisach

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=str(ROOT.parent / "shared" / "data" / "real"))
    ap.add_argument("--out", default=str(ROOT / "experiments" / "results" / "forc_preisach_cv.json"))
    a = ap.parse_args(argv)
    rec = load_record(Path(a.data) / "sma_wing_forc_train.csv")
    u_min, u_max = float(np.min(rec.u)), float(np.max(rec.u))
    rows = []
    for r in (0, 1, 2):
        t0 = time.time()
        split = make_split(rec, holdout_residue=r)
        print(f"== fold {r}: held out {split.test_labels}", file=sys.stderr, flush=True)
        base0, _ = choose_base(rec)
        base, _ = fit_extended(ExtendedModel(base0, ()), [], split)
        sat, _ = fit_extended(base, ["output_saturation"], split)
        row = {"holdout_residue": r, "heldout_branches": split.test_labels, "train_branches": split.train_labels, "models": {}}
        for name, m in (("eupi", base), ("eupi+output_saturation", sat)):
            _, te = _metrics_pair(m, split)
            row["models"][name] = {"heldout_e_r": te["e_r_percent"], "heldout_rmse": te["rmse"], "heldout_max_abs": te["max_abs_error"],
                                   "n_parameters": n_parameters(m)}
        pm, info = cv_fit_preisach(split.train, u_min, u_max, verbose=True)
        te = _heldout(pm, split)
        row["models"]["preisach"] = {"heldout_e_r": te["e_r_percent"], "heldout_rmse": te["rmse"], "heldout_max_abs": te["max_abs_error"],
                                     "n_levels": info["n_levels"], "lam": info["lam"], "n_weights_nominal": pm.n_relays + 1,
                                     "n_nonzero_weights": info["n_nonzero"], "effective_dof": info["dof"],
                                     "train_rmse": float(np.sqrt(info["sse"] / info["n"])), "inner_cv": info["inner_cv"],
                                     "inner_cv_rmse": info["chosen"]["cv_rmse"], "cv_table": info["cv_table"]}
        row["seconds"] = time.time() - t0
        rows.append(row)
        print(f"fold {r}: " + ", ".join(f"{k} e_r {v['heldout_e_r']:.2f} %" for k, v in row["models"].items())
              + f" ({row['seconds']:.0f} s)", file=sys.stderr, flush=True)
    doc = {"record": "sma_wing_forc_train.csv", "grids": {"n_levels": list(N_LEVELS_GRID), "lam": list(LAM_GRID)},
           "criterion": "pooled inner leave-one-branch-out RMSE", "folds": rows}
    atomic_write_json(a.out, doc)
    print("| held out | EUPI e_r / RMSE | EUPI+sat e_r / RMSE | Preisach e_r / RMSE | Preisach n_levels, lam | Preisach dof (nonzero / nominal) | EUPI+sat params |")
    print("|---|---|---|---|---|---|---|")
    for row in rows:
        e, s, p = (row["models"][k] for k in ("eupi", "eupi+output_saturation", "preisach"))
        print(f"| {row['holdout_residue']}: {row['heldout_branches']} | {e['heldout_e_r']:.2f} / {e['heldout_rmse']:.4f} | "
              f"{s['heldout_e_r']:.2f} / {s['heldout_rmse']:.4f} | {p['heldout_e_r']:.2f} / {p['heldout_rmse']:.4f} | "
              f"{p['n_levels']}, {p['lam']:.0e} | {p['effective_dof']:.1f} ({p['n_nonzero_weights']} / {p['n_weights_nominal']}) | {s['n_parameters']} |")


if __name__ == "__main__":
    main()
