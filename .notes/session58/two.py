"""Two default fits in one process (a batch script): what the second record pays."""
import sys, time, tempfile
from pathlib import Path
sys.path.insert(0, "tests")
import indep_plant, smafl_jax as sj
from smafl_jax.report import fit_record
specs = [tuple(a.split(":")) for a in sys.argv[1:]] or [("7", "pwm", "25"), ("11", "multisine", "25")]
for seed, drive, rate in specs:
    r = indep_plant.make_record(int(seed), drive=drive, rate_hz=float(rate), minutes=20.0 * 25 / float(rate), start="cold")
    p = Path(tempfile.mkdtemp()) / "rec.csv"; indep_plant.write_csv(p, r)
    rec = sj.load_record(p)
    t0 = time.perf_counter(); m, doc, _ = fit_record(rec); dt = time.perf_counter() - t0
    print(f"seed {seed} {drive} {rate} Hz n={len(rec)}: {dt:.1f} s, class {doc.get('model', {}).get('kind', '?')}, val {doc['metrics']['validation']['rmse']:.4g}", flush=True)
