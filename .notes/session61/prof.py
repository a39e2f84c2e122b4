"""Stage timing of the default fit on the benchmark record: progress lines with wall-clock stamps."""
import logging, sys, time, tempfile
from pathlib import Path
root = Path(sys.argv[1]).resolve()
sys.path.insert(0, str(root)); sys.path.insert(0, str(root / "tests"))
import indep_plant
import smafl_jax as sj
from smafl_jax.report import fit_record
logging.basicConfig(level=logging.INFO, format="%(relativeCreated)8.0f ms %(message)s", stream=sys.stdout)
r = indep_plant.make_record(7, drive="pwm", rate_hz=25, minutes=20.0, start="cold")
with tempfile.TemporaryDirectory() as tmp:
    p = Path(tmp) / "rec.csv"; indep_plant.write_csv(p, r); rec = sj.load_record(p)
    t0 = time.perf_counter(); _, doc, _ = fit_record(rec, progress=True)
    print("TOTAL", time.perf_counter() - t0, doc["settings"]["structure_choice"]["chosen"], doc["metrics"]["validation"]["rmse"] if "validation" in doc["metrics"] else "")
