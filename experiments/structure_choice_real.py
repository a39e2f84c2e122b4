"""Does the validation block of one real record pick the hysteresis class that carries to the OTHER runs of its rig?

The shared real records (../shared/data/real, read in place): NiTi wire electric 01-05 and water steps 01-04
(temperature_front_C -> length_signal), cavatappi 200 g s1_t1, s1_t2, s2_t1, s3_t1 (pressure -> displacement_mm,
resampled to 0.01 s).  Each record is fitted alone with each candidate class (`fit_record` defaults: EUPI as
``--model auto`` fits it, thresholds and tilts trained; Preisach) and the saved model is simulated on every other
record of its family (`simulate_record`, the fit's initial state).  Reported per record: validation RMSE of each
class (what `--model auto` compares), the class it picks, and the median RMSE ratio on the other runs
(Preisach / EUPI; < 1: Preisach carries better).

    OPENBLAS_NUM_THREADS=1 python experiments/structure_choice_real.py OUT.json [DATA_DIR]
"""

from __future__ import annotations

import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

FAMILIES = {
    "niti_electric": (
        [f"niti_wire_electric_0{i}.csv" for i in range(1, 6)],
        dict(input="temperature_front_C", output="length_signal"),
    ),
    "niti_water": (
        [f"niti_wire_water_step_0{i}.csv" for i in range(1, 5)],
        dict(input="temperature_front_C", output="length_signal"),
    ),
    "cavatappi_200g": (
        [f"cavatappi_pneumatic_200g_{s}.csv" for s in ("s1_t1", "s1_t2", "s2_t1", "s3_t1")],
        dict(input="pressure", output="displacement_mm", resample=0.01),
    ),
}
CLASSES = {"eupi": dict(model="eupi", thresholds=True, tilts=True), "preisach": dict(model="preisach")}


def main() -> None:
    import smafl_jax as sj
    from smafl_jax.report import fit_record, write_fit_outputs
    from smafl_jax.workflows.simulate import simulate_record

    out_path = Path(sys.argv[1])
    data = Path(sys.argv[2]) if len(sys.argv) > 2 else ROOT.parent / "shared" / "data" / "real"
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for fam, (files, kw) in FAMILIES.items():
            recs = {f: sj.load_record(data / f, **kw) for f in files}
            for f in files:
                row = {"family": fam, "file": f, "val_rmse": {}, "val_e_r": {}, "transfer_rmse": {}, "seconds": {}}
                for cls, opts in CLASSES.items():
                    t0 = time.perf_counter()
                    _, doc, masks = fit_record(recs[f], **opts)
                    row["seconds"][cls] = time.perf_counter() - t0
                    folder = Path(tmp) / f"{fam}_{f}_{cls}"
                    folder.mkdir()
                    write_fit_outputs(folder, recs[f], doc, masks, figures=False)
                    row["val_rmse"][cls] = doc["metrics"]["validation"]["rmse"]
                    row["val_e_r"][cls] = doc["metrics"]["validation"]["e_r_percent"]
                    row["transfer_rmse"][cls] = {
                        g: float(simulate_record(folder / "fit.json", recs[g]).scores["rmse"]) for g in files if g != f
                    }
                row["picked"] = min(row["val_rmse"], key=lambda c: row["val_rmse"][c])
                ratio = [
                    row["transfer_rmse"]["preisach"][g] / row["transfer_rmse"]["eupi"][g] for g in row["transfer_rmse"]["eupi"]
                ]
                row["transfer_ratio_median"] = float(np.median(ratio))
                rows.append(row)
                print(
                    f"{f}: val RMSE eupi {row['val_rmse']['eupi']:.4g}, preisach {row['val_rmse']['preisach']:.4g} -> "
                    f"{row['picked']}; other runs preisach/eupi median {row['transfer_ratio_median']:.2f}",
                    flush=True,
                )
    out_path.write_text(json.dumps(rows, indent=1))
    agree = sum((r["picked"] == "preisach") == (r["transfer_ratio_median"] < 1.0) for r in rows)
    print(f"validation pick agrees with the better class on the other runs for {agree}/{len(rows)} records")


if __name__ == "__main__":
    main()
