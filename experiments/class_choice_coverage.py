"""Does the validation coverage say when `--model auto`'s class choice is unreliable?  (issue 18, session 27)

Each record of the independent plant A (tests/indep_plant.py, plain numpy) is fitted on its first 70 % as each class
`--model auto` compares (`cascade`, `cascade-preisach`, `cascade-preisach-gauss`, thresholds and tilts trained as auto
trains them), and each saved model is scored on the last 30 % (RMSE / noise SD).  Per class the split fit's training
RMSE, validation RMSE and validation coverage (fit.json `split.coverage`) are stored, so class-choice rules can be
compared on what each would have kept.

    python experiments/class_choice_coverage.py OUT.jsonl SEED...            # plant A, random_levels cells (one process)
    python experiments/class_choice_coverage.py --plant-b OUT.jsonl SEED...  # plant B (experiments/indep_plant_b.py)
    python experiments/class_choice_coverage.py --matrix OUT.jsonl SEED...   # plant A, issue 18's matrix cells, 20 min
    python experiments/class_choice_coverage.py --table OUT.jsonl...                        # the rules compared
    python experiments/class_choice_coverage.py --ensembles OUT.jsonl...  # combinations of the classes' predictions
                                                                          # (OUT.preds/, written by the fits since session 28)
"""

from __future__ import annotations

import json
import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

CLASSES = ("cascade", "cascade-preisach", "cascade-preisach-gauss", "cascade-phase")
CELLS = {
    "random_levels cold 20 Hz length": dict(drive="random_levels", rate_hz=20, start="cold", orientation="length"),
    "random_levels warm 10 Hz": dict(drive="random_levels", rate_hz=10, start="warm"),
}
#: plant B (experiments/indep_plant_b.py: Gaussian Preisach or Ikuta hysteresis, V^2/R(T) heating with radiation), where
#: the EUPI cascade often cannot fit the training part: a rule that keeps the default class must not lose there
CELLS_B = {
    "B steps warm 5 Hz": dict(drive="steps", rate_hz=5, start="warm"),
    "B multisine cold 25 Hz": dict(drive="multisine", rate_hz=25, start="cold"),
    "B pwm mid 25 Hz length": dict(drive="pwm", rate_hz=25, start="mid", sensor="length"),
}
MINUTES = 5.0
#: ``--matrix``: issue 18's matrix cells (tests/indep_plant.MATRIX_CELLS) at the matrix's 20 minutes
MATRIX_MINUTES = 20.0


def _record(plant, seed, kw, folder=Path("/tmp")):
    """``(csv path, heldout_start, noise_sd)`` of one independent record."""
    p = folder / f"ccc_{plant}_{seed}_{kw['drive']}_{kw['rate_hz']}.csv"
    if plant in ("a", "matrix"):
        import indep_plant as ip

        r = ip.make_record(seed, minutes=MATRIX_MINUTES if plant == "matrix" else MINUTES, **kw)
        ip.write_csv(p, r)
    else:
        sys.path.insert(0, str(ROOT / "experiments"))
        import indep_plant_b as pb

        r = pb.make_record(seed, minutes=MINUTES, **kw)
        pb.write_csv(p, r)
    return p, r["heldout_start"], r["noise_sd"]


def _cells(plant):
    if plant == "matrix":
        import indep_plant as ip

        return ip.MATRIX_CELLS
    return CELLS if plant == "a" else CELLS_B


def fits(out, seeds, plant="a"):
    import smafl_jax as sj
    from smafl_jax.report import fit_record

    for seed in seeds:
        for cell, kw in _cells(plant).items():
            p, h0, sd = _record(plant, seed, kw)
            rec = sj.load_record(p)
            p70 = p.with_name(p.stem + "_70.csv")
            sj.atomic_write_csv(p70, {"time_s": rec.time[:h0], "voltage_V": rec.u[:h0], "displacement_mm": rec.y[:h0]})
            for cls in CLASSES:
                t0 = time.time()
                model, doc, _ = fit_record(sj.load_record(p70), model=cls, thresholds=True, tilts=True)
                yhat = np.asarray(sj.simulate(model, rec.u, rec.dt))
                e = yhat - rec.y
                # predictions beside OUT, so combinations of the classes can be scored without refitting
                preds = Path(out).with_suffix(".preds")
                preds.mkdir(exist_ok=True)
                np.savez(preds / f"{plant}_{seed}_{cell.replace(' ', '_')}_{cls}.npz", yhat=yhat, y=rec.y, h0=h0, sd=sd)
                row = dict(
                    cell=cell,
                    seed=seed,
                    cls=cls,
                    noise_sd=sd,
                    train_rmse=float(doc["metrics"]["train"]["rmse"]),  # the split fit on its training samples
                    val_rmse=float(doc["metrics"]["validation"]["rmse"]),
                    coverage=(doc["split"].get("coverage") or {}).get("covered_fraction"),
                    train_x=float(np.sqrt(np.mean(e[:h0] ** 2)) / sd),
                    held_x=float(np.sqrt(np.mean(e[h0:] ** 2)) / sd),
                    seconds=time.time() - t0,
                )
                print(json.dumps(row), flush=True)
                with open(out, "a") as f:
                    f.write(json.dumps(row) + "\n")


def table(paths):
    recs = {}
    for path in paths:
        for line in open(path):
            r = json.loads(line)
            recs.setdefault((r["cell"], r["seed"]), {})[r["cls"]] = r
    full = {k: v for k, v in recs.items() if set(v) == set(CLASSES)}

    def gm(x):
        return math.exp(sum(math.log(max(a, 1e-9)) for a in x) / len(x))

    def val(v):
        return min(v, key=lambda c: v[c]["val_rmse"])

    def guard(v, tol=1.05):  # a class worse than the default on the split's training samples is not kept
        ok = [c for c in v if c == "cascade" or v[c]["train_rmse"] <= tol * v["cascade"]["train_rmse"]]
        return min(ok, key=lambda c: v[c]["val_rmse"])

    def extrapolating(v):
        return all(v[c]["coverage"] is not None and v[c]["coverage"] < 0.9 for c in v)

    def default_when_extrapolating(v):
        return "cascade" if extrapolating(v) else val(v)

    def guard_when_extrapolating(v):
        return guard(v) if extrapolating(v) else val(v)

    def default_unless_it_cannot_fit(v, margin=0.8):
        # every class extrapolates: the default class, unless another fits the split's training samples clearly better
        if not extrapolating(v):
            return val(v)
        better = [c for c in v if c != "cascade" and v[c]["train_rmse"] <= margin * v["cascade"]["train_rmse"]]
        return min(better, key=lambda c: v[c]["val_rmse"]) if better else "cascade"

    rules = {
        "lowest validation RMSE (today)": val,
        "training guard (<= 1.05x the EUPI cascade)": guard,
        "EUPI cascade when every class extrapolates": default_when_extrapolating,
        "training guard when every class extrapolates": guard_when_extrapolating,
        "EUPI cascade when every class extrapolates, unless another trains <= 0.8x": default_unless_it_cannot_fit,
        "always the EUPI cascade": lambda v: "cascade",
        "oracle (best held-out)": lambda v: min(v, key=lambda c: v[c]["held_x"]),
    }
    print("| record | flagged | " + " | ".join(f"{c} train / val / cov / held-out" for c in CLASSES) + " |")
    print("|---|---|" + "---|" * len(CLASSES))
    for k, v in sorted(full.items()):
        cells = " | ".join(
            f"{v[c]['train_rmse'] / v[c]['noise_sd']:.2f} / {v[c]['val_rmse'] / v[c]['noise_sd']:.2f} / "
            f"{100 * (v[c]['coverage'] or 0):.0f} % / {v[c]['held_x']:.2f}"
            for c in CLASSES
        )
        print(f"| {k[0]} s{k[1]} | {'yes' if extrapolating(v) else 'no'} | {cells} |")
    print(
        f"\n{len(full)} records ({sum(extrapolating(v) for v in full.values())} flagged); held-out / noise of the class each rule keeps:\n"
    )
    print("| rule | geometric mean | within 1.5x | within 3x |")
    print("|---|---|---|---|")
    for name, rule in rules.items():
        h = [v[rule(v)]["held_x"] for v in full.values()]
        print(f"| {name} | {gm(h):.2f} | {sum(x <= 1.5 for x in h)} | {sum(x <= 3 for x in h)} |")


def ensembles(paths):
    """Held-out / noise of combinations of the three classes' predictions (session 28): does averaging the classes beat
    choosing one?  The median of three is robust to one class that blows up on an untrained branch."""
    for path in paths:
        recs = {}
        for line in open(path):
            r = json.loads(line)
            recs.setdefault((r["cell"], r["seed"]), {})[r["cls"]] = r
        res = {}
        for (cell, seed), v in sorted(recs.items()):
            files = [
                next(iter(Path(path).with_suffix(".preds").glob(f"*_{seed}_{cell.replace(' ', '_')}_{c}.npz")), None)
                for c in CLASSES
            ]
            if len(v) < len(CLASSES) or None in files:
                continue
            P = {c: np.load(f) for c, f in zip(CLASSES, files)}
            y, h0, sd = P["cascade"]["y"], int(P["cascade"]["h0"]), float(P["cascade"]["sd"])
            Y = {c: P[c]["yhat"] for c in CLASSES}

            def held(yh):
                return float(np.sqrt(np.mean((yh[h0:] - y[h0:]) ** 2)) / sd)

            best = min(CLASSES, key=lambda c: v[c]["val_rmse"])
            order = sorted(CLASSES, key=lambda c: v[c]["val_rmse"])
            w = np.array([1 / v[c]["val_rmse"] ** 2 for c in CLASSES])
            median = held(np.median(np.stack([Y[c] for c in CLASSES]), 0))
            flagged = all((v[c]["coverage"] or 0) < 0.9 for c in CLASSES)
            # classes that fit the split's training samples about as well as the EUPI cascade (the training guard)
            ok = [c for c in CLASSES if c == "cascade" or v[c]["train_rmse"] <= 1.05 * v["cascade"]["train_rmse"]]
            rows = {
                "lowest validation RMSE (today)": held(Y[best]),
                "median of the classes that pass the training guard": held(np.median(np.stack([Y[c] for c in ok]), 0)),
                "mean of the three": held(sum(Y.values()) / 3),
                "median of the three": median,
                "mean of the two best by validation": held((Y[order[0]] + Y[order[1]]) / 2),
                "weights 1 / validation MSE": held(sum(wi / w.sum() * Y[c] for wi, c in zip(w, CLASSES))),
                "median when every class extrapolates, else validation": median if flagged else held(Y[best]),
                "always the EUPI cascade": held(Y["cascade"]),
                "oracle class": min(held(Y[c]) for c in CLASSES),
            }
            for k, x in rows.items():
                res.setdefault(k, []).append(x)
        n = len(next(iter(res.values()), []))
        print(f"\n{path}: {n} records\n\n| rule | geometric mean | within 1.5x | within 3x |\n|---|---|---|---|")
        for k, x in res.items():
            gmean = math.exp(sum(math.log(max(a, 1e-9)) for a in x) / len(x))
            print(f"| {k} | {gmean:.2f} | {sum(a <= 1.5 for a in x)} | {sum(a <= 3 for a in x)} |")


if __name__ == "__main__":
    if sys.argv[1] == "--table":
        table(sys.argv[2:])
    elif sys.argv[1] == "--ensembles":
        ensembles(sys.argv[2:])
    elif sys.argv[1] == "--plant-b":
        fits(sys.argv[2], [int(s) for s in sys.argv[3:]], plant="b")
    elif sys.argv[1] == "--matrix":
        fits(sys.argv[2], [int(s) for s in sys.argv[3:]], plant="matrix")
    else:
        fits(sys.argv[1], [int(s) for s in sys.argv[2:]])
