"""Issue 13: the diagnosis' base (screened, variable projection, symmetric refinement) on clean independent records,
with and without the gain prior of `smafl fit` (`fit(..., gain_prior=KAPPA)` applied after every `refine_model`).

A prototype measurement (the diagnosis itself has no gain prior): held-out RMSE / noise of the refined base, and which
memory rule / drive lag the held-out block chose, per seed of `indep_effects.make_effect_record(TRUTH, seed)`.

Run:  OPENBLAS_NUM_THREADS=1 python experiments/diagnose_base_gain_prior.py OUT.jsonl 0,1,2,3,4,5,6,7,8,9 [none] [1.0]
"""

import json
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import indep_effects as ie

import smafl_jax.diagnosis._diagnose as D  # private: refine_model is patched to add the prior
from smafl_jax.identify._fit import fit  # private: the gain prior stage of fit (solver None: prior only)

ORIGINAL = D.refine_model


def refine_with_prior(kappa):
    def refine(model, split, *, max_steps=D.REFINE_MAX_STEPS):
        m = ORIGINAL(model, split, max_steps=max_steps)
        if kappa is None:
            return m
        data = [(s.u, s.y, s.dt) for s in split.train]
        weights = [s.mask.astype(float) for s in split.train]
        return fit(m, data, init=None, solver=None, weights=weights, gain_prior=kappa).model

    return refine


def main(out, seeds, truth="none", kappa=1.0):
    for seed in seeds:
        with tempfile.TemporaryDirectory() as tmp:
            rec, case, split, screened, vp = ie.diagnosis_start(tmp, truth, seed)
            noise = case["noise_rms_measured"]
            row = {"seed": seed, "truth": truth}
            for k in (None, kappa):
                D.refine_model = refine_with_prior(k)
                t0 = time.time()
                m, _, doc = D.refined_base(vp, screened, split)
                row[str(k)] = {
                    "held_over_noise": D._held(m, split)["rmse"] / noise,
                    "chosen": doc["chosen"],
                    "s": time.time() - t0,
                }
            D.refine_model = ORIGINAL
            print(json.dumps(row), flush=True)
            with open(out, "a") as f:
                f.write(json.dumps(row) + "\n")


if __name__ == "__main__":
    a = sys.argv[1:]
    main(a[0], [int(s) for s in a[1].split(",")], a[2] if len(a) > 2 else "none", float(a[3]) if len(a) > 3 else 1.0)
