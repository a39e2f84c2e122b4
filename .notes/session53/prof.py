import sys, time, tempfile, threading, functools, collections
from pathlib import Path
root = Path(sys.argv[1]); sys.path.insert(0, str(root)); sys.path.insert(0, str(root / "tests"))
import indep_plant, smafl_jax as sj
from smafl_jax.report import fit_record
import smafl_jax.report._report_fit as RF, smafl_jax.identify._choose as CH, smafl_jax.identify._fit as FI, smafl_jax.identify._memory_search as MS
T0 = time.perf_counter()
def wrap(mod, name):
    f = getattr(mod, name)
    @functools.wraps(f)
    def w(*a, **k):
        t = time.perf_counter()
        try: return f(*a, **k)
        finally:
            print(f"{time.perf_counter()-T0:6.1f} {threading.current_thread().name[-12:]:12s} {name:28s} {time.perf_counter()-t:6.2f}", flush=True)
    setattr(mod, name, w)
for mod, names in [(RF, ["fitted_memory_start", "fit", "_refit_whole", "_polish", "screen_start", "simulate"]), (CH, ["search_memory"] if hasattr(CH,"search_memory") else []), (MS, ["search_memory"]), (FI, ["_solve_optx", "init_linear"])]:
    for n in names:
        if hasattr(mod, n): wrap(mod, n)
r = indep_plant.make_record(7, drive="pwm", rate_hz=25, minutes=20.0, start="cold")
p = Path(tempfile.mkdtemp()) / "rec.csv"; indep_plant.write_csv(p, r)
rec = sj.load_record(p)
t0 = time.perf_counter(); m, doc, _ = fit_record(rec); print("total", time.perf_counter() - t0)
