"""Stage timing of the default fit on the benchmark record: progress lines with wall-clock stamps."""
import logging, sys, time, tempfile
from pathlib import Path
root = Path(sys.argv[1]).resolve()
sys.path.insert(0, str(root)); sys.path.insert(0, str(root / "tests"))
import indep_plant
import smafl_jax as sj
from smafl_jax.report import fit_record
import jax, collections, threading
DUR=collections.defaultdict(float); CNT=collections.Counter(); LOCK=threading.Lock()
def _lis(event, dur, **kw):
    with LOCK:
        DUR[event]+=dur; CNT[event]+=1
jax.monitoring.register_event_duration_secs_listener(_lis)
jax.config.update("jax_log_compiles", True)
class H(logging.Handler):
    def emit(self, rec):
        msg=rec.getMessage()
        import re
        m=re.search(r"Finished XLA compilation of (.*) in ([0-9.e-]+) sec", msg)
        if m:
            with LOCK: COMP.append((m.group(1), float(m.group(2)), rec.relativeCreated))
COMP=[]
logging.getLogger("jax").addHandler(H()); logging.getLogger("jax").setLevel(logging.DEBUG); logging.getLogger("jax").propagate=False
logging.basicConfig(level=logging.INFO, format="%(relativeCreated)8.0f ms %(message)s", stream=sys.stdout)
r = indep_plant.make_record(7, drive="pwm", rate_hz=25, minutes=20.0, start="cold")
with tempfile.TemporaryDirectory() as tmp:
    p = Path(tmp) / "rec.csv"; indep_plant.write_csv(p, r); rec = sj.load_record(p)
    t0 = time.perf_counter(); _, doc, _ = fit_record(rec, progress=True)
    print("TOTAL", time.perf_counter() - t0, doc["settings"]["structure_choice"]["chosen"], doc["metrics"]["validation"]["rmse"] if "validation" in doc["metrics"] else "")

for k in sorted(DUR, key=lambda k:-DUR[k]): print(f"{DUR[k]:8.1f} s {CNT[k]:5d} {k}")

agg=collections.defaultdict(lambda:[0,0.0])
for n,t,_ in COMP: agg[n][0]+=1; agg[n][1]+=t
print("compiles", len(COMP), sum(t for _,t,_ in COMP))
for n,(c,t) in sorted(agg.items(), key=lambda kv:-kv[1][1])[:40]: print(f"{t:7.2f} s {c:3d} {n[:150]}")
