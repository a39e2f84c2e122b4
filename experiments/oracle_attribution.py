"""Ceiling of blind attribution on the independent simulator (issue 13): does the TRUE effect help at all?

For each record of `experiments/indep_effects.py` (one per truth and seed) the diagnosis' own split and base are
built (`make_split`, `choose_base`, `screened_base`, `fit_extended(.., [])`), and the catalogue effect named like the
truth is fitted as `smafl diagnose` fits a candidate (`fit_extended`).  Then base and candidate are each refined
with the SAME freedom (LM over gains, thermal rate, effect parameters, thresholds and tilts; `fit` from the fitted
model, training samples only).  Printed: held-out RMSE / noise of the base and the true-effect model, profiled and
refined, and the held-out gain 1 - ext/base.  On the clean record ("none") every catalogue effect is fitted the same
way: the gains a selection rule must reject.

If the true effect's gain is small, or no larger than what effects reach on the clean record, no selection rule can
attribute that record: the ceiling is the model class / the fit, not the rule.

Run:  OPENBLAS_NUM_THREADS=1 python experiments/oracle_attribution.py --seeds 0 1 2 [--out results/oracle_attribution.jsonl]
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "experiments"))

import indep_effects as ie  # noqa: E402

TRUTHS = ("resistance_tc", "asymmetric_cooling", "ambient_drift", "nonlinear_cooling", "rate_dependence", "creep", "delay")


def _train_data(split):
    """Training data of a split for `fit`: ``(data, weights)``; the model runs from the segment start."""
    return [(s.u, s.y, s.dt) for s in split.train], [s.mask.astype(float) for s in split.train]


def _spec(model):
    """Trainable spec of ``model`` with the hysteresis thresholds and tilts freed as well."""
    import equinox as eqx

    from smafl_jax.effects.extended import ExtendedModel
    from smafl_jax.models import hysteresis_of

    spec = model.trainable_spec(load=False) if isinstance(model, ExtendedModel) else None
    h = hysteresis_of(model)
    free = [f for f in h.fixed_fields() if f not in h.fixed_fields(("thresholds", "tilts"))]

    def where(s):
        return [getattr(hysteresis_of(s), f) for f in free]

    return eqx.tree_at(where, spec, [True] * len(free))


def refine(model, split, max_steps=200):
    from smafl_jax.identify import fit

    data, w = _train_data(split)
    res = fit(model, data, trainable=_spec(model), init=None, weights=w, max_steps=max_steps)
    ok = np.isfinite(res.loss) and res.loss <= res.init_loss
    return res.model if ok else model


def held(model, split):
    from smafl_jax.diagnosis import score

    return score(model, split.test)[0]["rmse"]


def run(truth, seed, folder, effects):
    from smafl_jax.diagnosis import fit_extended
    from smafl_jax.identify import fitted_memory_start

    t0 = time.time()
    rec, case, split, screened, base_p = ie.diagnosis_start(folder, truth, seed)
    noise = case["noise_rms_measured"]
    base_r = refine(base_p, split)
    # the operator memory at t = 0 fitted, as `smafl fit` may choose it (its validation block decides there)
    data, w = _train_data(split)
    fm = fitted_memory_start(screened, data, w)
    base_m = refine(fit_extended(fm[0], [], split)[0], split) if fm is not None else base_r
    row = {
        "truth": truth,
        "seed": seed,
        "variant": case.get("effect_variant"),
        "drive": case["drive"],
        "effect_over_noise": case.get("effect_over_noise"),
        "base_profiled": held(base_p, split) / noise,
        "base_refined": held(base_r, split) / noise,
        "base_memory": held(base_m, split) / noise,
        "effects": {},
    }
    for name in effects:
        try:
            ext_p, _ = fit_extended(screened, [name], split)
        except ValueError as exc:  # not applicable to this record
            row["effects"][name] = {"error": str(exc)[:120]}
            continue
        ext_r = refine(ext_p, split)
        ext_m = refine(fit_extended(base_m, [name], split)[0], split)
        hp, hr, hm = (held(m, split) / noise for m in (ext_p, ext_r, ext_m))
        row["effects"][name] = {
            "profiled": hp,
            "refined": hr,
            "memory": hm,
            "gain_profiled": 1 - hp / row["base_profiled"],
            "gain_refined": 1 - hr / row["base_refined"],
            "gain_memory": 1 - hm / row["base_memory"],
        }
    row["seconds"] = time.time() - t0
    return row


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[0])
    ap.add_argument("--truths", nargs="+", default=("none",) + TRUTHS)
    ap.add_argument("--out", type=Path, default=ROOT / "experiments" / "results" / "oracle_attribution.jsonl")
    a = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as folder:
        for seed in a.seeds:
            for truth in a.truths:
                effects = TRUTHS if truth == "none" else (truth,)
                row = run(truth, seed, folder, effects)
                line = json.dumps(row)
                print(line, flush=True)
                with open(a.out, "a") as fh:
                    fh.write(line + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
