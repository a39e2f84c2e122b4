"""Does a fold score choose the class better than the validation block?  A confirmation set (session 21).

Session 20's `--model auto` keeps the class (EUPI cascade or Preisach cascade) with the lower RMSE on the split's one
validation block.  On the 39 plant-B records it was tuned on, rules that use more held-out blocks looked better (the 5
blocks = training blocks 2-5 of a blocked 5-fold CV with the gains re-solved per fold, plus the validation block; majority
of blocks gm 11.3x vs 12.7x the noise).  This script checks such rules on records none of them saw: fresh plant-B seeds
(experiments/indep_plant_b.py, seeds 4 and 5: 24 records) and one plant-A seed (tests/indep_plant.py, the 5 matrix
cells).  Every record is fitted as BOTH candidates that `--model auto` fits (`smafl fit --model cascade --thresholds
--tilts` and `--model cascade-preisach`, CLI in a subprocess, first 70 %), then each saved model is scored on the last
30 % (RMSE / noise SD), and each split model's fold SSEs and validation SSE are computed (`identify._choose.fold_sse`).

    python experiments/class_choice_confirm.py                 # the fits, in parallel processes (results to $OUT)
    # environment: CF_WORKERS (14), CF_SECONDS (470: no new fit after it), CF_SEEDS_B ('4 5'), CF_SEEDS_A ('23'),
    # CF_CLASSES ('E P'; 'G': the Gaussian-density Preisach cascade), CF_ONLY (a record-name substring), CF_RATES
    # (plant-B sample rates, e.g. '25 5'); work folder /tmp/cf_work
    python experiments/class_choice_confirm.py --table [JSONL]  # the rules compared on the results
    python experiments/class_choice_confirm.py --classes JSONL...  # auto over E+P vs E+P+G (session 22)

Measured (session 21, the fits run on a lent 16-core machine, 15 processes, 495 s): results in
experiments/results/class_choice_confirm_session21.jsonl; the table is in experiments/results/class_choice_confirm.md.
"""

import json
import math
import os
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "experiments"), str(ROOT / "tests")]
OUT = Path(os.environ.get("OUT", "/tmp/cf_out"))
OUT.mkdir(parents=True, exist_ok=True)
WORK = Path("/tmp/cf_work")
WORK.mkdir(exist_ok=True)
DEADLINE = time.time() + float(os.environ.get("CF_SECONDS", "470"))
WORKERS = int(os.environ.get("CF_WORKERS", "14"))
CLASSES = {
    "E": ["--model", "cascade", "--thresholds", "--tilts"],
    "P": ["--model", "cascade-preisach"],
    "G": ["--model", "cascade-preisach-gauss"],
}


def records():
    import fit_plant_b as fb
    import indep_plant as pa

    out = []
    for c in fb.grid([int(s) for s in os.environ.get("CF_SEEDS_B", "4 5").split()], 10.0)[:-3]:
        out.append(("B", fb.name_of(c), c))
    for s in [int(s) for s in os.environ.get("CF_SEEDS_A", "23").split()]:
        for cell, kw in pa.MATRIX_CELLS.items():
            out.append(("A", f"A{s}_" + cell.replace(", ", "_").replace(" ", ""), dict(seed=s, **kw)))
    return out


def make(kind, name, c):
    import smafl_jax as sj

    d = WORK / name
    d.mkdir(exist_ok=True)
    if kind == "B":
        import indep_plant_b as pb

        r = pb.make_record(c["seed"], **{k: v for k, v in c.items() if k != "seed"})
        h0 = r["heldout_start"]
        pb.write_csv(d / "first70.csv", r, stop=h0)
        u, y, dt, sd = r["voltage"], r["output"], 1.0 / c["rate_hz"], r["noise_sd"]
        truth = r["truth"]["hysteresis"]["class"]
    else:
        import indep_plant as pa

        r = pa.make_record(c["seed"], minutes=10, **{k: v for k, v in c.items() if k != "seed"})
        h0 = r["heldout_start"]
        sj.atomic_write_csv(
            d / "first70.csv", {"time_s": r["time"][:h0], "voltage_V": r["u"][:h0], "displacement_mm": r["y"][:h0]}
        )
        u, y, dt, sd = r["u"], r["y"], float(r["time"][1] - r["time"][0]), r["noise_sd"]
        truth = "eupi"
    np.savez(d / "full.npz", u=u, y=y, dt=dt, sd=sd, h0=h0)
    return d, truth


def job(args):
    kind, name, c, cls, d, truth = args
    if time.time() > DEADLINE - 60:
        return {"name": name, "cls": cls, "skipped": True}
    out = d / f"fit_{cls}"
    env = dict(
        os.environ,
        OPENBLAS_NUM_THREADS="1",
        OMP_NUM_THREADS="1",
        JAX_PLATFORMS="cpu",
        XLA_FLAGS="--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1",
        PYTHONPATH=os.environ.get("PYTHONPATH", "") + ":" + str(ROOT),
    )
    t0 = time.time()
    try:
        p = subprocess.run(
            [sys.executable, "-m", "smafl_jax", "fit", str(d / "first70.csv"), "--out", str(out), "--no-figures", *CLASSES[cls]],
            env=env,
            capture_output=True,
            text=True,
            timeout=max(10, DEADLINE - time.time()),
        )
    except subprocess.TimeoutExpired:
        return {"name": name, "cls": cls, "timeout": True, "wall": time.time() - t0}
    row = {"name": name, "kind": kind, "truth": truth, "cls": cls, "rc": p.returncode, "wall": time.time() - t0}
    if p.returncode:
        row["err"] = p.stderr[-400:]
        return row
    env2 = dict(env)
    q = subprocess.run(
        [sys.executable, __file__, "--score", str(d), str(out / "fit.json")], env=env2, capture_output=True, text=True
    )
    try:
        row.update(json.loads(q.stdout.strip().splitlines()[-1]))
    except (IndexError, json.JSONDecodeError):
        row["score_err"] = q.stderr[-400:]
    return row


def score(d, fj):
    import smafl_jax as sj
    from smafl_jax.identify._choose import fold_sse  # private: the fold score under test is not a public function

    z = np.load(Path(d) / "full.npz")
    h0 = int(z["h0"])
    doc = json.loads(Path(fj).read_text())
    m = sj.load_model(fj)
    yh = np.asarray(sj.simulate(m, z["u"], float(z["dt"])))
    sm = sj.model_from_dict(doc["split_model"] or doc["model"])
    rec = sj.load_record(Path(d) / "first70.csv")
    tr, va, _ = sj.split_masks(rec, "auto", val_fraction=0.3)
    f = fold_sse(sm, rec, [tr.astype(float)])
    ys = np.asarray(sj.simulate(sm, rec.u, rec.dt))
    print(
        json.dumps(
            {
                "held_x": float(np.sqrt(np.mean((yh[h0:] - z["y"][h0:]) ** 2)) / float(z["sd"])),
                "train_x": float(np.sqrt(np.mean((yh[:h0] - z["y"][:h0]) ** 2)) / float(z["sd"])),
                "fold": f,
                "val_sse": float(np.sum((ys[va] - rec.y[va]) ** 2)),
                "val_rmse": doc["metrics"]["validation"]["rmse"],
                "screen_fold": min(
                    [
                        sum(e["fold_sse_of_structure"][1:])
                        for e in (doc["settings"]["start_screening"] or [])
                        if e.get("fold_sse_of_structure")
                    ]
                    or [None]
                ),
            }
        )
    )


RESULTS = ROOT / "experiments" / "results" / "class_choice_confirm_session21.jsonl"


def _gm(v):
    return math.exp(sum(math.log(x) for x in v) / len(v)) if v else float("nan")


def table(path=RESULTS):
    """The class-choice rules compared on the confirmation fits: geometric mean held-out / noise, counts."""
    fits = {}
    for line in Path(path).read_text().splitlines():
        r = json.loads(line)
        if r.get("held_x") is not None:
            fits.setdefault(r["name"], {})[r["cls"]] = r
    fits = {n: v for n, v in fits.items() if len(v) == 2}

    def blocks(f):
        return f["fold"][1:] + [f["val_sse"]]

    rules = {
        "validation block (session 20 rule)": lambda f: f["P"]["val_sse"] < f["E"]["val_sse"],
        "training folds 2-5": lambda f: sum(f["P"]["fold"][1:]) < sum(f["E"]["fold"][1:]),
        "screening folds 2-5 (before refinement)": lambda f: f["P"]["screen_fold"] < f["E"]["screen_fold"],
        "median of the 5 blocks": lambda f: sorted(blocks(f["P"]))[2] < sorted(blocks(f["E"]))[2],
        "majority of the 5 blocks": lambda f: sum(p < e for p, e in zip(blocks(f["P"]), blocks(f["E"]))) >= 3,
    }
    print(
        "| rule | plant | records | auto held-out gm | EUPI alone gm | best-of-two gm | within 3x | within 1.5x | worse than EUPI by >10 % | right class |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for label, rule in rules.items():
        for kind in ("B", "A"):
            names = [n for n in fits if fits[n]["E"]["kind"] == kind]
            if not names:
                continue
            seeds = sorted({int(n[1:].split("_")[0]) for n in names})
            plant = f"{kind} (seeds {', '.join(map(str, seeds))})"
            e = [fits[n]["E"]["held_x"] for n in names]
            h = [fits[n]["P"]["held_x"] if rule(fits[n]) else fits[n]["E"]["held_x"] for n in names]
            best = [min(fits[n]["P"]["held_x"], fits[n]["E"]["held_x"]) for n in names]
            right = sum((fits[n]["P"]["held_x"] < fits[n]["E"]["held_x"]) == rule(fits[n]) for n in names)
            print(
                f"| {label} | {plant} | {len(names)} | {_gm(h):.2f}x | {_gm(e):.2f}x | {_gm(best):.2f}x | {sum(x <= 3 for x in h)} | "
                f"{sum(x <= 1.5 for x in h)} | {sum(a > 1.1 * b for a, b in zip(h, e))} | {right} |"
            )
    print()
    print("| record | truth | EUPI held-out | Preisach held-out | EUPI val SSE | Preisach val SSE |")
    print("|---|---|---|---|---|---|")
    for n, f in fits.items():
        print(
            f"| {n} | {f['E']['truth']} | {f['E']['held_x']:.2f}x | {f['P']['held_x']:.2f}x | {f['E']['val_sse']:.4g} | {f['P']['val_sse']:.4g} |"
        )


def table_classes(*paths):
    """Session 22: auto's rule (lower validation RMSE) over the EUPI and Preisach cascades (E, P) against the same rule
    with the Gaussian-density Preisach cascade (G) as a third class, on records fitted as all three (rows of any of
    ``paths``; a record's later rows replace earlier ones of the same class)."""
    fits = {}
    for path in paths:
        for line in Path(path).read_text().splitlines():
            r = json.loads(line)
            if r.get("held_x") is not None:
                fits.setdefault(r["name"], {})[r["cls"]] = r
    fits = {n: v for n, v in fits.items() if all(c in v for c in "EPG")}

    def auto(f, classes):
        return f[min(classes, key=lambda c: f[c]["val_rmse"])]["held_x"]

    print(
        "| plant | records | rule over | auto held-out gm | within 1.5x | within 3x | better than E+P by >10 % | worse than E+P by >10 % |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for kind in ("B", "A"):
        names = [n for n in fits if fits[n]["E"]["kind"] == kind]
        if not names:
            continue
        seeds = sorted({n[1:].split("_")[0] for n in names})
        base = [auto(fits[n], "EP") for n in names]
        for classes in ("E", "EP", "EG", "EPG"):
            h = [auto(fits[n], classes) for n in names]
            print(
                f"| {kind} (seeds {', '.join(seeds)}) | {len(names)} | {'+'.join(classes)} | {_gm(h):.2f}x | {sum(x <= 1.5 for x in h)} | "
                f"{sum(x <= 3 for x in h)} | {sum(a < b / 1.1 for a, b in zip(h, base))} | {sum(a > 1.1 * b for a, b in zip(h, base))} |"
            )
    print()
    print("| record | E held-out | P held-out | G held-out | E val RMSE | P val RMSE | G val RMSE |")
    print("|---|---|---|---|---|---|---|")
    for n, f in fits.items():
        print(
            f"| {n} | {f['E']['held_x']:.2f}x | {f['P']['held_x']:.2f}x | {f['G']['held_x']:.2f}x | {f['E']['val_rmse']:.4g} | "
            f"{f['P']['val_rmse']:.4g} | {f['G']['val_rmse']:.4g} |"
        )


if __name__ == "__main__":
    if sys.argv[1:2] == ["--classes"]:
        table_classes(*sys.argv[2:])
        sys.exit(0)
    if sys.argv[1:2] == ["--score"]:
        score(*sys.argv[2:4])
        sys.exit(0)
    if sys.argv[1:2] == ["--table"]:
        table(*sys.argv[2:3])
        sys.exit(0)
    rates = os.environ.get("CF_RATES", "").split()  # plant-B sample rates to keep (e.g. '25 5'); all when unset
    recs = [
        r
        for r in records()
        if os.environ.get("CF_ONLY", "") in r[1] and (not rates or r[0] != "B" or f"{r[2]['rate_hz']:g}" in rates)
    ]
    jobs = []
    for kind, name, c in recs:
        d, truth = make(kind, name, c)
        for cls in os.environ.get("CF_CLASSES", "E P").split():
            jobs.append((kind, name, c, cls, d, truth))
    # longest first: 100 Hz plant-B records
    jobs.sort(key=lambda j: -(j[2].get("rate_hz", 25) if j[0] == "B" else 30))
    print(f"{len(jobs)} fits, {WORKERS} workers", flush=True)
    with open(OUT / "confirm.jsonl", "w") as fh, ThreadPoolExecutor(WORKERS) as ex:
        for row in ex.map(job, jobs):
            fh.write(json.dumps(row) + "\n")
            fh.flush()
            print(
                row.get("name"),
                row.get("cls"),
                row.get("held_x"),
                row.get("wall"),
                row.get("err", "")[-200:] if row.get("err") else "",
                flush=True,
            )
