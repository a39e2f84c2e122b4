"""Transfer to other runs of the rig, before/after: `fit_record` defaults (model auto) from one code root, the saved model
simulated on every other record of its family (median RMSE), for the real records where session 22's auto kept the
Gaussian-density Preisach.  python transfer_probe.py CODE_ROOT OUT.jsonl"""
import json, sys, tempfile, time
from pathlib import Path
root, out = sys.argv[1], sys.argv[2]
sys.path.insert(0, str(Path(root).resolve()))
sys.path.insert(0, str(Path(root).resolve() / "experiments"))
import numpy as np
import smafl_jax as sj
from smafl_jax.report import fit_record, write_fit_outputs
from smafl_jax.workflows.simulate import simulate_record
from structure_choice_real import FAMILIES
data = Path('/work/shared/data/real')
KEEP = {"niti_wire_electric_02.csv", "niti_wire_electric_04.csv", "cavatappi_pneumatic_200g_s1_t2.csv",
        "cavatappi_pneumatic_200g_s2_t1.csv", "cavatappi_pneumatic_200g_s3_t1.csv"}
with tempfile.TemporaryDirectory() as tmp:
    for fam, (files, kw) in FAMILIES.items():
        if not KEEP & set(files):
            continue
        recs = {f: sj.load_record(data / f, **kw) for f in files}
        for f in sorted(KEEP & set(files)):
            t0 = time.perf_counter()
            model, doc, masks = fit_record(recs[f])
            folder = Path(tmp) / f; folder.mkdir()
            write_fit_outputs(folder, recs[f], doc, masks, figures=False)
            others = {g: float(simulate_record(folder / "fit.json", recs[g]).scores["rmse"]) for g in files if g != f}
            row = {"file": f, "root": root, "chosen": (doc["settings"].get("structure_choice") or {}).get("chosen"),
                   "val_rmse": doc["metrics"]["validation"]["rmse"], "transfer": others,
                   "transfer_median": float(np.median(list(others.values()))), "seconds": time.perf_counter() - t0}
            print(json.dumps(row), flush=True)
            open(out, "a").write(json.dumps(row) + "\n")
