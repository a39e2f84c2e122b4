"""Compile time and count during one default fit of the benchmark record (jax.monitoring duration events)."""
import sys, time, tempfile, collections
from pathlib import Path
sys.path.insert(0, "/work/main/tests"); import indep_plant
import jax, jax.monitoring as mon
import smafl_jax as sj
from smafl_jax.report import fit_record
dur = collections.defaultdict(float); cnt = collections.Counter()
def on(event, d, **kw):
    dur[event] += d; cnt[event] += 1
mon.register_event_duration_secs_listener(on)
r = indep_plant.make_record(7, drive="pwm", rate_hz=25, minutes=20.0, start="cold")
with tempfile.TemporaryDirectory() as tmp:
    p = Path(tmp) / "rec.csv"; indep_plant.write_csv(p, r); rec = sj.load_record(p)
    for i in range(int(sys.argv[1]) if len(sys.argv) > 1 else 1):
        dur.clear(); cnt.clear()
        t = time.perf_counter(); fit_record(rec); wall = time.perf_counter() - t
        print(f"run {i}: wall {wall:.1f} s")
        for k in sorted(dur, key=dur.get, reverse=True)[:8]: print(f"   {k}: {dur[k]:.1f} s over {cnt[k]} events")
