import sys, time, tempfile, threading, os
from pathlib import Path
root = Path(sys.argv[1]); sys.path.insert(0, str(root)); sys.path.insert(0, str(root / "tests"))
import indep_plant, smafl_jax as sj
from smafl_jax.report import fit_record
r = indep_plant.make_record(7, drive="pwm", rate_hz=25, minutes=20.0, start="cold")
p = Path(tempfile.mkdtemp()) / "rec.csv"; indep_plant.write_csv(p, r)
rec = sj.load_record(p)
samples = []; stop = False
def sampler():
    tck = os.sysconf("SC_CLK_TCK"); last = None
    while not stop:
        f = open("/proc/self/stat").read().split(); cpu = (int(f[13]) + int(f[14])) / tck
        samples.append((time.perf_counter(), cpu)); time.sleep(2.0)
threading.Thread(target=sampler, daemon=True).start()
t0 = time.perf_counter(); m, doc, _ = fit_record(rec); dt = time.perf_counter() - t0; stop = True
print("total", round(dt,1))
for (a, ca), (b, cb) in zip(samples, samples[1:]):
    print(f"{a-t0:6.1f} {(cb-ca)/(b-a):4.2f}", end=" |")
print()
