import sys, time, tempfile, logging, re, collections
from pathlib import Path
sys.path.insert(0, "/work/main/tests"); import indep_plant
import jax
jax.config.update("jax_log_compiles", True)
import smafl_jax as sj
from smafl_jax.report import fit_record
per = collections.defaultdict(list)
class H(logging.Handler):
    def emit(self, rec):
        m = re.search(r"Finished XLA compilation of (.+?) in ([0-9.e-]+) sec", rec.getMessage())
        if m: per[m.group(1)].append(float(m.group(2)))
h = H(); 
for name in ("jax", "jax._src"):
    logging.getLogger(name).addHandler(h)
logging.getLogger("jax").setLevel(logging.DEBUG)
r = indep_plant.make_record(7, drive="pwm", rate_hz=25, minutes=20.0, start="cold")
with tempfile.TemporaryDirectory() as tmp:
    p = Path(tmp) / "rec.csv"; indep_plant.write_csv(p, r); rec = sj.load_record(p)
    t = time.perf_counter(); fit_record(rec); print("wall", time.perf_counter() - t)
tot = sum(sum(v) for v in per.values()); print("total compile", round(tot,1), "programs", sum(len(v) for v in per.values()))
for k, v in sorted(per.items(), key=lambda kv: -sum(kv[1]))[:40]:
    print(f"{sum(v):6.1f} s {len(v):4d}x  max {max(v):5.2f}  {k[:110]}")
