"""Default `smafl fit` (fit_record defaults) on the shared real records, one code root at a time.

    python experiments/fit_real_before_after.py CODE_ROOT OUT.json [DATA_DIR]
    python experiments/fit_real_before_after.py --table OLD.json NEW.json

SMAFL_FIT_OPTS='{"solver": "varpro"}' (JSON) passes keyword options to `fit_record`, to compare settings of one tree.

CODE_ROOT is the checkout whose smafl_jax is imported (an older commit: `git archive COMMIT | tar -x -C /tmp/old`),
so two versions fit the same records side by side.  Every record: the default split (time or branch), the held-out
(validation) RMSE and e_r of the model fitted on the training part, the saved model's orientation and the seconds.
The real records are read in place (../shared/data/real/, never copied into the repository).
"""

import json
import os
import sys
import time
from pathlib import Path

JOBS = [
    ("sma_wing_forc_train.csv", {}),
    *[(f"niti_wire_electric_0{i}.csv", dict(input="temperature_front_C", output="length_signal")) for i in range(1, 6)],
    *[(f"niti_wire_water_step_0{i}.csv", dict(input="temperature_front_C", output="length_signal")) for i in range(1, 5)],
    *[
        (f"cavatappi_pneumatic_200g_{s}.csv", dict(input="pressure", output="displacement_mm", resample=0.01))
        for s in ("s1_t1", "s1_t2", "s2_t1", "s3_t1")
    ],
]

if sys.argv[1] == "--table":
    old, new = (json.load(open(p)) for p in sys.argv[2:4])
    print("| record | before: held-out RMSE | e_r % | s | after: held-out RMSE | e_r % | s | orientation before -> after |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for a, b in zip(old, new):
        print(
            f"| {a['file']} | {a['rmse']:.4g} | {a['e_r']:.1f} | {a['seconds']:.0f} | {b['rmse']:.4g} | {b['e_r']:.1f} | "
            f"{b['seconds']:.0f} | {a['orientation']} -> {b['orientation']} |"
        )
    sys.exit(0)

root, out = sys.argv[1], sys.argv[2]
data = Path(sys.argv[3] if len(sys.argv) > 3 else Path(__file__).resolve().parents[1].parent / "shared" / "data" / "real")
sys.path.insert(0, str(Path(root).resolve()))
import smafl_jax as sj  # noqa: E402
from smafl_jax.report import fit_record  # noqa: E402

OPTS = json.loads(os.environ.get("SMAFL_FIT_OPTS", "{}"))  # keyword options of fit_record, e.g. '{"solver": "varpro"}'
rows = []
for name, kw in JOBS:
    rec = sj.load_record(data / name, **kw)
    t0 = time.time()
    model, doc, _ = fit_record(rec, **OPTS)
    v = doc["metrics"]["validation"]
    hy = getattr(model, "hysteresis", model)
    rows.append(
        dict(
            file=name,
            n=len(rec),
            rmse=v["rmse"],
            e_r=v["e_r_percent"],
            seconds=time.time() - t0,
            orientation=int(getattr(hy, "orientation", 0)),
            notes=[n for n in doc["notes"] if "orientation" in n],
        )
    )
    print(json.dumps(rows[-1]), flush=True)
    json.dump(rows, open(out, "w"), indent=1)
