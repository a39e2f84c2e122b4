import sys, tempfile, cProfile, pstats
from pathlib import Path
sys.path.insert(0, "tests")
import indep_plant, smafl_jax as sj
from smafl_jax.report import fit_record
r = indep_plant.make_record(7, drive="pwm", rate_hz=25, minutes=20.0, start="cold")
p = Path(tempfile.mkdtemp()) / "rec.csv"; indep_plant.write_csv(p, r)
rec = sj.load_record(p)
pr = cProfile.Profile(); pr.enable()
fit_record(rec, model="cascade")
pr.disable()
st = pstats.Stats(pr); st.sort_stats("cumulative").print_stats(60)
