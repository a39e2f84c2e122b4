import sys, time, logging, tempfile
from pathlib import Path
sys.path.insert(0, "tests")
import indep_plant
import smafl_jax as sj
from smafl_jax.report import fit_record
from smafl_jax._progress import LOGGER
t0 = time.time()
class H(logging.Handler):
    def emit(self, r):
        print(f"{time.time()-t0:6.1f} {r.getMessage()[:150]}", flush=True)
LOGGER.addHandler(H()); LOGGER.setLevel(logging.INFO)
r = indep_plant.make_record(7, drive="pwm", rate_hz=25, minutes=20.0, start="cold")
p = Path(tempfile.mkdtemp()) / "rec.csv"
indep_plant.write_csv(p, r)
fit_record(sj.load_record(p), progress=True)
print("total", time.time() - t0)
