"""The gain prior (`smafl fit --gain-prior`) on the shared real records: in-record validation and other runs of the rig.

Every record is fitted with `fit_record` defaults twice, without the prior (``gain_prior=None``, the fit before
session 16) and with it (the default, kappa 1).  Reported per record and setting: the held-out (validation) RMSE and
e_r of the split fit, the class `--model auto` kept, the largest operator gain of the saved model, and the saved
model simulated on every other record of its rig from the fit's initial state (`simulate_record`): median RMSE.

    OPENBLAS_NUM_THREADS=1 python experiments/gain_prior_real.py OUT.jsonl FAMILY [FAMILY ...] [--data DIR]
    python experiments/gain_prior_real.py --table OUT.jsonl [OUT2.jsonl ...]

GAIN_PRIOR_SETTINGS='{"kappa1": 1.0, "kappa0.1": 0.1}' (JSON, name -> kappa or null) replaces the two settings; the
table compares the first two settings of each row (the second against the first).

FAMILY: niti_electric, niti_water, cavatappi_200g, sma_wing.  The real records are read in place (../shared/data/real).
"""

from __future__ import annotations

import json
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

sys.path.insert(0, str(ROOT / "experiments"))
from structure_choice_real import FAMILIES as RIGS  # noqa: E402  (the same records and columns)

FAMILIES = {**RIGS, "sma_wing": (["sma_wing_forc_train.csv"], {})}
SETTINGS = json.loads(os.environ.get("GAIN_PRIOR_SETTINGS", '{"none": null, "kappa1": 1.0}'))


def table(paths):
    rows = [json.loads(line) for p in paths for line in open(p) if line.strip()]
    first, second = [k for k in rows[0] if k not in ("family", "file")][:2]
    print(f"| record | class {first} / {second} | validation RMSE | e_r % | largest gain | other runs median RMSE |")
    print("| --- | --- | --- | --- | --- | --- |")
    ratios = []
    for r in rows:
        a, b = r[first], r[second]
        other = "-"
        if a["transfer_median"] is not None:
            other = f"{a['transfer_median']:.4g} -> {b['transfer_median']:.4g}"
            ratios.append(b["transfer_median"] / a["transfer_median"])
        print(
            f"| {r['file']} | {a['chosen']} / {b['chosen']} | {a['val_rmse']:.4g} -> {b['val_rmse']:.4g} | "
            f"{a['val_e_r']:.3g} -> {b['val_e_r']:.3g} | {a['largest_gain']:.4g} -> {b['largest_gain']:.4g} | {other} |"
        )
    if ratios:
        q = np.array(ratios)
        print(
            f"\nother runs, {second} / {first}: geometric mean {np.exp(np.mean(np.log(q))):.3g}, median {np.median(q):.3g}, "
            f"better {int(np.sum(q < 0.99))}, equal {int(np.sum(np.abs(q - 1) <= 0.01))}, worse {int(np.sum(q > 1.01))} "
            f"of {len(q)}"
        )
    v = np.array([r[second]["val_rmse"] / r[first]["val_rmse"] for r in rows])
    print(
        f"validation RMSE, {second} / {first}: geometric mean {np.exp(np.mean(np.log(v))):.3g}, worst {v.max():.3g}, "
        f"best {v.min():.3g} ({len(v)} records)"
    )


def main(argv):
    import smafl_jax as sj
    from smafl_jax.models import hysteresis_of
    from smafl_jax.report import fit_record, write_fit_outputs
    from smafl_jax.workflows.simulate import simulate_record

    data = ROOT.parent / "shared" / "data" / "real"
    if "--data" in argv:
        i = argv.index("--data")
        data = Path(argv[i + 1])
        argv = argv[:i] + argv[i + 2 :]
    out, fams = Path(argv[0]), argv[1:]
    with tempfile.TemporaryDirectory() as tmp:
        for fam in fams:
            files, kw = FAMILIES[fam]
            recs = {f: sj.load_record(data / f, **kw) for f in files}
            for f in files:
                row = {"family": fam, "file": f}
                for name, kappa in SETTINGS.items():
                    t0 = time.perf_counter()
                    model, doc, masks = fit_record(recs[f], gain_prior=kappa)
                    folder = Path(tmp) / f"{f}_{name}"
                    folder.mkdir()
                    write_fit_outputs(folder, recs[f], doc, masks, figures=False)
                    h = hysteresis_of(model)
                    nonneg = np.asarray(h.nonnegative_columns())
                    others = {g: float(simulate_record(folder / "fit.json", recs[g]).scores["rmse"]) for g in files if g != f}
                    row[name] = {
                        "chosen": (doc["settings"].get("structure_choice") or {}).get("chosen", doc["settings"]["structure"]),
                        "val_rmse": doc["metrics"]["validation"]["rmse"],
                        "val_e_r": doc["metrics"]["validation"]["e_r_percent"],
                        "largest_gain": float(np.max(np.asarray(h.linear_weights())[nonneg])),
                        "transfer": others,
                        "transfer_median": float(np.median(list(others.values()))) if others else None,
                        "seconds": time.perf_counter() - t0,
                    }
                print(json.dumps(row), flush=True)
                with open(out, "a") as fh:
                    fh.write(json.dumps(row) + "\n")


if __name__ == "__main__":
    if sys.argv[1] == "--table":
        table(sys.argv[2:])
    else:
        main(sys.argv[1:])
