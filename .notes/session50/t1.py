import sys, time, tempfile
from pathlib import Path
root = Path(sys.argv[1]); sys.path.insert(0, str(root)); sys.path.insert(0, str(root / "tests"))
import indep_plant, smafl_jax as sj
from smafl_jax.report import fit_record
assert sj.__file__.startswith(str(root)), sj.__file__
r = indep_plant.make_record(7, drive="pwm", rate_hz=25, minutes=20.0, start="cold")
p = Path(tempfile.mkdtemp()) / "rec.csv"; indep_plant.write_csv(p, r)
rec = sj.load_record(p)
t0 = time.perf_counter(); m, doc, _ = fit_record(rec, **({"model": sys.argv[2]} if len(sys.argv) > 2 else {})); dt = time.perf_counter() - t0
print(f"{root} {dt:.1f} s val {doc['metrics']['validation']['rmse']:.6g} whole {doc['metrics']['whole_record']['rmse']:.6g}", flush=True)
