"""Timeline of a default fit of the benchmark record: progress lines with wall-clock stamps."""
import sys, time, tempfile, logging
from pathlib import Path
sys.path.insert(0, "/work/main/tests"); import indep_plant
import smafl_jax as sj
from smafl_jax.report import fit_record
T0 = time.perf_counter()
class H(logging.Handler):
    def emit(self, rec): print(f"{time.perf_counter()-T0:7.1f} [{rec.name}] {rec.getMessage()[:150]}", flush=True)
logging.getLogger("smafl_jax").addHandler(H()); logging.getLogger("smafl_jax").setLevel(logging.INFO)
r = indep_plant.make_record(7, drive="pwm", rate_hz=25, minutes=20.0, start="cold")
with tempfile.TemporaryDirectory() as tmp:
    p = Path(tmp) / "rec.csv"; indep_plant.write_csv(p, r); rec = sj.load_record(p)
    t = time.perf_counter(); _, doc, _ = fit_record(rec, progress=True); print("total", time.perf_counter() - t)
    print({c["structure"]: round(c["seconds"], 1) for c in doc["settings"]["structure_choice"]["candidates"]})
