"""Discrete Preisach model vs EUPI on the SMA FORC record: outer 3-fold branch CV, inner CV on training branches (issue 6).

Run:  OPENBLAS_NUM_THREADS=1 python experiments/forc_preisach_cv.py [--data ../shared/data/real]
      [--out experiments/results/forc_preisach_cv.json]
Outer folds: branches with label % 3 == r held out (r = 0, 1, 2; branch 0, the major loop, always trains),
as `smafl_jax.diagnosis._diagnose.make_split`.  Per fold:
  - base EUPI and EUPI + output_saturation: the diagnosis' VarPro fits (fixed default grids, no tuning);
  - Preisach: (n_levels, lam) chosen by leave-one-branch-out CV over the outer-training FORCs only
    (`cv_fit_preisach`, criterion pooled inner RMSE), refitted on all outer-training branches.
Held-out e_r (eq. 3) and RMSE are reported; the held-out branches never enter any choice.
Two further rows per fold:
  - Preisach with crisp relays (``ramp=False``), the model before ramp relays (same CV);
  - a model-free floor: each held-out descending branch predicted by linear interpolation, in reversal
    voltage, of its two trained neighbours at the same input values (the rising part is the major loop).
    Any model smooth in the reversal voltage does about this well; points where the measured branch leaves
    the band of its neighbours are out of reach.
``--lobo`` adds leave-one-branch-out (every descending branch predicted from all the others, inner CV nested:
the situation of the deployed model, refitted on every branch and asked for a new one); pooled e_r.
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


def neighbour_interpolation(train, test_seg):
    """Model-free prediction of one FORC: its trained neighbours (by reversal voltage) interpolated linearly."""
    u, y = np.asarray(test_seg.u), np.asarray(test_seg.y)
    a = float(u.max())
    branches = sorted(((float(np.max(s.u)), s) for s in train), key=lambda t: t[0])
    rev = np.array([t[0] for t in branches])
    lo = branches[int(np.searchsorted(rev, a) - 1)] if np.any(rev < a) else branches[0]
    hi = branches[int(np.searchsorted(rev, a))] if np.any(rev >= a) else branches[-1]

    def descending(s):
        k = int(np.argmax(s.u))
        return np.asarray(s.u)[k:], np.asarray(s.y)[k:]

    k = int(np.argmax(u))
    pred = np.empty_like(y)
    major = max(train, key=lambda s: float(np.max(s.u)))
    mu, my = np.asarray(major.u)[: int(np.argmax(major.u)) + 1], np.asarray(major.y)[: int(np.argmax(major.u)) + 1]
    pred[: k + 1] = np.interp(u[: k + 1], mu, my)  # rising part: the major loop
    vals = []
    for _, s in (lo, hi):
        du, dy = descending(s)
        vals.append(np.interp(u[k:], du[::-1], dy[::-1]))
    f = 0.0 if hi[0] == lo[0] else (a - lo[0]) / (hi[0] - lo[0])
    pred[k:] = (1 - f) * vals[0] + f * vals[1]
    return pred


def lobo(rec, u_min, u_max, verbose=True):
    """Leave-one-branch-out over the descending FORCs (branch 0 always trains), nested inner CV; pooled metrics."""
    from smafl_jax import metrics
    from smafl_jax.diagnosis import whole_record_split
    from smafl_jax.models import cv_fit_preisach

    segs = whole_record_split(rec).train
    labels = list(dict.fromkeys(np.asarray(rec.extra["branch"]).astype(int).tolist()))
    ys, yh, per = [], [], []
    for i, lab in enumerate(labels):
        if lab == 0:
            continue
        pm, info = cv_fit_preisach([s for j, s in enumerate(segs) if j != i], u_min, u_max)
        p = np.asarray(pm.simulate(segs[i].u))
        e = np.abs(segs[i].y - p)
        per.append(
            {
                "branch": lab,
                "max_abs_error": float(e.max()),
                "at_input": float(segs[i].u[int(np.argmax(e))]),
                "n_levels": info["n_levels"],
                "lam": info["lam"],
                "method": info["method"],
            }
        )
        if verbose:
            print(
                f"  LOBO branch {lab}: max |error| {e.max():.3f} at {segs[i].u[int(np.argmax(e))]:.2f} "
                f"(n_levels {info['n_levels']}, {info['method']}, lam {info['lam']})",
                file=sys.stderr,
                flush=True,
            )
        ys.append(segs[i].y)
        yh.append(p)
    m = metrics(np.concatenate(ys), np.concatenate(yh))
    out = {"pooled": m, "branches": per, "fixed_everett_35": {}}
    from smafl_jax.models import EVERETT_INTERPOLANTS, Preisach, fit_everett

    for interp in EVERETT_INTERPOLANTS:  # for reference: one fixed identification, no inner choice
        ys2, yh2 = [], []
        for i, lab in enumerate(labels):
            if lab != 0:
                pe, _ = fit_everett(
                    Preisach.from_range(u_min, u_max, n_levels=35), [s for j, s in enumerate(segs) if j != i], interp
                )
                ys2.append(segs[i].y)
                yh2.append(np.asarray(pe.simulate(segs[i].u)))
        out["fixed_everett_35"][interp] = metrics(np.concatenate(ys2), np.concatenate(yh2))
    return out


def main(argv=None):
    from smafl_jax import atomic_write_json, load_record, metrics
    from smafl_jax.diagnosis import choose_base, fit_extended, make_split, n_parameters
    from smafl_jax.diagnosis._diagnose import _metrics_pair  # private: diagnosis helper, no public equivalent
    from smafl_jax.effects import ExtendedModel
    from smafl_jax.models import EVERETT_INTERPOLANTS, LAM_GRID, N_LEVELS_GRID, Preisach, cv_fit_preisach, fit_everett

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=str(ROOT.parent / "shared" / "data" / "real"))
    ap.add_argument("--out", default=str(ROOT / "experiments" / "results" / "forc_preisach_cv.json"))
    ap.add_argument("--lobo", action="store_true", help="also leave-one-branch-out with nested inner CV (about 2 min on 2 cores)")
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
            row["models"][name] = {
                "heldout_e_r": te["e_r_percent"],
                "heldout_rmse": te["rmse"],
                "heldout_max_abs": te["max_abs_error"],
                "n_parameters": n_parameters(m),
            }
        pm, info = cv_fit_preisach(split.train, u_min, u_max, verbose=True)
        te = _heldout(pm, split)
        row["models"]["preisach"] = {
            "heldout_e_r": te["e_r_percent"],
            "heldout_rmse": te["rmse"],
            "heldout_max_abs": te["max_abs_error"],
            "n_levels": info["n_levels"],
            "lam": info["lam"],
            "method": info["method"],
            "n_weights_nominal": pm.n_relays + 1,
            "n_nonzero_weights": info["n_nonzero"],
            "effective_dof": info["dof"],
            "train_rmse": float(np.sqrt(info["sse"] / info["n"])),
            "inner_cv": info["inner_cv"],
            "inner_cv_rmse": info["chosen"]["cv_rmse"],
            "cv_table": info["cv_table"],
        }
        pc, info_c = cv_fit_preisach(split.train, u_min, u_max, ramp=False)
        te = _heldout(pc, split)
        row["models"]["preisach_crisp"] = {
            "heldout_e_r": te["e_r_percent"],
            "heldout_rmse": te["rmse"],
            "heldout_max_abs": te["max_abs_error"],
            "n_levels": info_c["n_levels"],
            "lam": info_c["lam"],
        }
        for interp in EVERETT_INTERPOLANTS:  # fixed choices, shown for reference (the inner CV above may pick one of them)
            pe, _ = fit_everett(Preisach.from_range(u_min, u_max, n_levels=35), split.train, interp)
            te = _heldout(pe, split)
            row["models"][f"everett_{interp}_35"] = {
                "heldout_e_r": te["e_r_percent"],
                "heldout_rmse": te["rmse"],
                "heldout_max_abs": te["max_abs_error"],
                "inner_cv_rmse": next(
                    r["cv_rmse"] for r in info["cv_table"] if r["method"] == f"everett-{interp}" and r["n_levels"] == 35
                ),
            }
        y = np.concatenate([s.y for s in split.test])
        yi = np.concatenate([neighbour_interpolation(split.train, s) for s in split.test])
        te = metrics(y, yi)
        row["models"]["neighbour_interpolation"] = {
            "heldout_e_r": te["e_r_percent"],
            "heldout_rmse": te["rmse"],
            "heldout_max_abs": te["max_abs_error"],
        }
        row["seconds"] = time.time() - t0
        rows.append(row)
        print(
            f"fold {r}: "
            + ", ".join(f"{k} e_r {v['heldout_e_r']:.2f} %" for k, v in row["models"].items())
            + f" ({row['seconds']:.0f} s)",
            file=sys.stderr,
            flush=True,
        )
    doc = {
        "record": "sma_wing_forc_train.csv",
        "grids": {"n_levels": list(N_LEVELS_GRID), "lam": list(LAM_GRID)},
        "criterion": "pooled inner leave-one-branch-out RMSE",
        "relays": "ramp (width = one level cell) unless named crisp",
        "folds": rows,
    }
    if a.lobo:
        doc["lobo"] = lobo(rec, u_min, u_max)
    atomic_write_json(a.out, doc)
    print(
        "| held out | EUPI e_r / RMSE | EUPI+sat e_r / RMSE | Preisach e_r / RMSE | Preisach n_levels, lam | Preisach dof (nonzero / nominal) | EUPI+sat params "
        "| crisp Preisach e_r | neighbour interpolation e_r | Everett spline / pchip / linear e_r (inner-CV RMSE) |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for row in rows:
        e, s, p = (row["models"][k] for k in ("eupi", "eupi+output_saturation", "preisach"))
        print(
            f"| {row['holdout_residue']}: {row['heldout_branches']} | {e['heldout_e_r']:.2f} / {e['heldout_rmse']:.4f} | "
            f"{s['heldout_e_r']:.2f} / {s['heldout_rmse']:.4f} | {p['heldout_e_r']:.2f} / {p['heldout_rmse']:.4f} | "
            f"{p['n_levels']}, {p['method'] if p['lam'] is None else format(p['lam'], '.0e')} | {p['effective_dof']:.1f} ({p['n_nonzero_weights']} / {p['n_weights_nominal']}) | {s['n_parameters']} "
            f"| {row['models']['preisach_crisp']['heldout_e_r']:.2f} | {row['models']['neighbour_interpolation']['heldout_e_r']:.2f} | "
            + " / ".join(
                f"{row['models'][f'everett_{k}_35']['heldout_e_r']:.2f} ({row['models'][f'everett_{k}_35']['inner_cv_rmse']:.3f})"
                for k in ("spline", "pchip", "linear")
            )
            + " |"
        )
    if a.lobo:
        lb = doc["lobo"]
        print(
            f"LOBO (every descending branch from all the others, nested inner CV): pooled e_r {lb['pooled']['e_r_percent']:.2f} %, "
            f"RMSE {lb['pooled']['rmse']:.4f}; worst: "
            + ", ".join(
                f"branch {r['branch']} {r['max_abs_error']:.3f} at {r['at_input']:.1f}"
                for r in sorted(lb["branches"], key=lambda r: -r["max_abs_error"])[:3]
            )
        )
        print(
            "LOBO, fixed Everett identification on 35 levels (no inner choice): "
            + ", ".join(f"{k} e_r {v['e_r_percent']:.2f} % (RMSE {v['rmse']:.4f})" for k, v in lb["fixed_everett_35"].items())
        )


if __name__ == "__main__":
    main()
