import sys, time, tempfile, collections, logging, re
from pathlib import Path
sys.path.insert(0, "tests")
import jax
jax.config.update("jax_log_compiles", True)
D = collections.defaultdict(float); N = collections.Counter()
class H(logging.Handler):
    def emit(self, r):
        m = r.getMessage()
        g = re.search(r"Finished XLA compilation of (.+?) in ([0-9.e-]+) sec", m)
        if g: D[g.group(1)] += float(g.group(2)); N[g.group(1)] += 1
h = H(); h.setLevel(logging.DEBUG)
for name in ["jax._src.interpreters.pxla", "jax._src.dispatch", "jax"]:
    lg = logging.getLogger(name); lg.addHandler(h); lg.setLevel(logging.DEBUG); lg.propagate = False
import indep_plant
import smafl_jax as sj
from smafl_jax.report import fit_record
r = indep_plant.make_record(7, drive="pwm", rate_hz=25, minutes=20.0, start="cold")
p = Path(tempfile.mkdtemp()) / "rec.csv"
indep_plant.write_csv(p, r)
t0 = time.time()
import json; fit_record(sj.load_record(p), model=sys.argv[1] if len(sys.argv) > 1 else "auto", **(json.loads(sys.argv[2]) if len(sys.argv) > 2 else {}))
print("total", time.time() - t0, "compiles", sum(N.values()), "sec", sum(D.values()))
for k in sorted(D, key=lambda k: -D[k])[:45]: print(f"{k[:90]:90s} {N[k]:4d} {D[k]:7.2f}")
