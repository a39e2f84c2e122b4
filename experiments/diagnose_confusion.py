"""Confusion table of the blind effect diagnosis on synthetic records (issue 6).

Each record: the true cascade (datasets/truth.json) driven by the bundled drives
(steps, main loop, minor loops; dt 0.5 s), plus one catalogue effect with a
random seeded strength (or none), plus 3 um Gaussian noise.  The diagnosis runs
blind (`smafl_jax.diagnosis._diagnose.diagnose`); rows = true effect, columns = selection.

Run:  python experiments/diagnose_confusion.py --seeds 3 [--jobs 2] [--out experiments/results/diagnose_confusion.json]
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def _gen():
    spec = importlib.util.spec_from_file_location("smafl_datasets_generate", ROOT / "datasets" / "generate.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def run_one(args):
    effect, seed = args
    import smafl_jax as sj
    from smafl_jax.diagnosis import diagnose, synthetic_effect_record

    truth = sj.load_model(ROOT / "datasets" / "truth.json")
    rec, true = synthetic_effect_record(truth, _gen().drives(), effect, seed)
    t0 = time.time()
    res = diagnose(rec, verbose=False).report
    return {
        "true": effect or "none",
        "seed": seed,
        "true_parameters": {e.name: {k: float(getattr(e, k)) for k in e.parameters if hasattr(e, k)} for e in true.effects},
        "selected": res["selected"],
        "top_evidence": res["evidence_ranking"][0],
        "base_heldout_rmse": res["base"]["heldout_rmse"],
        "extended_heldout_rmse": res["extended"]["heldout_rmse"],
        "seconds": time.time() - t0,
    }


def main(argv=None):
    from smafl_jax.effects import EFFECT_NAMES

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--first-seed", type=int, default=100)
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--effects", nargs="*", default=None)
    ap.add_argument("--out", default=str(ROOT / "experiments" / "results" / "diagnose_confusion.json"))
    a = ap.parse_args(argv)
    effects = [None] + list(a.effects or EFFECT_NAMES)
    jobs = [(e, a.first_seed + 1000 * i + s) for i, e in enumerate(effects) for s in range(a.seeds)]
    rows = []
    with ProcessPoolExecutor(a.jobs) if a.jobs > 1 else _Serial() as ex:
        for r in ex.map(run_one, jobs):
            rows.append(r)
            print(
                f"{r['true']:>20s} seed {r['seed']}: selected {r['selected'] or ['none']}  held-out RMSE "
                f"{r['base_heldout_rmse']:.4f} -> {r['extended_heldout_rmse']:.4f} mm ({r['seconds']:.0f} s)",
                file=sys.stderr,
                flush=True,
            )
    names = ["none"] + list(EFFECT_NAMES)
    table = {t: {c: 0 for c in names + ["other-combination"]} for t in names}
    for r in rows:
        sel = r["selected"]
        col = "none" if not sel else (sel[0] if len(sel) == 1 else ("other-combination" if r["true"] not in sel else r["true"]))
        table[r["true"]][col] += 1
    correct = sum(
        1
        for r in rows
        if (r["true"] == "none" and not r["selected"]) or (r["true"] != "none" and r["selected"][:1] == [r["true"]])
    )
    reduced = [r for r in rows if r["true"] != "none"]
    cut = sum(1 for r in reduced if r["extended_heldout_rmse"] < 0.95 * r["base_heldout_rmse"])
    md = ["| true \\ selected | " + " | ".join(names) + " | combo |", "|" + "---|" * (len(names) + 2)]
    for t in names:
        if any(r["true"] == t for r in rows):
            md.append(f"| {t} | " + " | ".join(str(table[t][c]) for c in names) + f" | {table[t]['other-combination']} |")
    summary = {"n_records": len(rows), "correct": correct, "heldout_rmse_cut_5pct": f"{cut}/{len(reduced)}"}
    out = Path(a.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    from smafl_jax import atomic_write_json

    atomic_write_json(out, {"summary": summary, "table": table, "markdown": "\n".join(md), "rows": rows})
    print("\n".join(md))
    print(json.dumps(summary))


class _Serial:
    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    def map(self, fn, it):
        return map(fn, it)


if __name__ == "__main__":
    main()
