"""Class choice with the rescaled-branch class (session 54), on per-class fits of experiments/class_choice_coverage.py.

    python experiments/results/class_choice_phase_session54/rules.py experiments/results/class_choice_phase_session54/*.jsonl

Each row is one class fitted alone on a record's first 70 % (`fit_record(model=CLASS, thresholds=True, tilts=True)`)
and scored on the last 30 % (``held_x``: RMSE / noise SD).  `auto` below is `fit_record`'s rule (lowest validation RMSE;
the EUPI cascade kept when within `DEFAULT_CLASS_MARGIN` = 2 of it and no worse in training), applied to a set of classes.
"""

import collections
import json
import math
import sys

ALL = ("cascade", "cascade-preisach", "cascade-preisach-gauss", "cascade-phase")
MARGIN = 2.0


def gm(x):
    return math.exp(sum(math.log(max(a, 1e-9)) for a in x) / len(x))


def auto(v, classes):
    best = min(classes, key=lambda c: v[c]["val_rmse"])
    d = v["cascade"]
    keep_default = d["val_rmse"] < MARGIN * v[best]["val_rmse"] and d["train_rmse"] <= v[best]["train_rmse"]
    return "cascade" if best != "cascade" and keep_default else best


SETS = {
    "before: EUPI, Preisach, Gaussian Preisach": ALL[:3],
    "all four": ALL,
    "after: EUPI, Gaussian Preisach, phase": ("cascade", "cascade-preisach-gauss", "cascade-phase"),
    "EUPI, Preisach, phase": ("cascade", "cascade-preisach", "cascade-phase"),
}


def main(paths):
    recs = collections.defaultdict(dict)
    for path in paths:
        for line in open(path):
            r = json.loads(line)
            recs[(path.split("/")[-1].rsplit("_s", 1)[0], r["cell"], r["seed"])][r["cls"]] = r
    full = {k: v for k, v in recs.items() if set(v) >= set(ALL)}
    for g in [*sorted({k[0] for k in full}), "all"]:
        sel = [v for k, v in full.items() if g in ("all", k[0])]
        print(f"\n## {g}: {len(sel)} records\n\n| auto over | geometric mean | within 1.5x | within 3x | oracle gm |")
        print("|---|---|---|---|---|")
        for name, classes in SETS.items():
            h = [v[auto(v, classes)]["held_x"] for v in sel]
            best = [min(v[c]["held_x"] for c in classes) for v in sel]
            print(f"| {name} | {gm(h):.2f} | {sum(x <= 1.5 for x in h)} | {sum(x <= 3 for x in h)} | {gm(best):.2f} |")
    print(
        "\n| record | "
        + " | ".join(f"{c} train / val / held" for c in ALL)
        + " | before | after |\n|---|---|---|---|---|---|---|"
    )
    for k, v in sorted(full.items()):
        sd = v["cascade"]["noise_sd"]
        cells = " | ".join(f"{v[c]['train_rmse'] / sd:.1f} / {v[c]['val_rmse'] / sd:.1f} / {v[c]['held_x']:.1f}" for c in ALL)
        before, after = (
            auto(v, SETS[s]) for s in ("before: EUPI, Preisach, Gaussian Preisach", "after: EUPI, Gaussian Preisach, phase")
        )
        print(f"| {k[0]} {k[1]} s{k[2]} | {cells} | {before} | {after} |")


if __name__ == "__main__":
    main(sys.argv[1:])
