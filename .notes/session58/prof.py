"""cProfile of one default fit_record of the benchmark record, candidates one at a time (main thread)."""
import sys, cProfile, pstats, tempfile, time
from pathlib import Path
sys.path.insert(0, "tests")
import indep_plant, smafl_jax as sj
from smafl_jax.report import _report_fit, fit_record
_report_fit.candidate_threads = lambda n: 1
r = indep_plant.make_record(7, drive="pwm", rate_hz=25, minutes=20.0, start="cold")
p = Path(tempfile.mkdtemp()) / "rec.csv"; indep_plant.write_csv(p, r)
rec = sj.load_record(p)
pr = cProfile.Profile(); t0 = time.perf_counter(); pr.enable()
fit_record(rec)
pr.disable(); print("wall", time.perf_counter() - t0)
pr.dump_stats(sys.argv[1])
