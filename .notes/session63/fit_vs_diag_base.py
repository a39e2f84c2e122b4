"""Session 63: `smafl fit` (defaults) on the diagnosis' training part of independent effect records, scored on the
diagnosis' held-out part (the saved fit.json simulated from t = 0 over the whole record), beside the diagnosis' base.
python fit_vs_diag_base.py WORK TRUTH:SEED [...]"""
import json, os, subprocess, sys, tempfile, time
from pathlib import Path
import numpy as np
sys.path.insert(0, "experiments")
import indep_effects as ie
import smafl_jax as sj
from smafl_jax.diagnosis import _diagnose as D

work = Path(sys.argv[1])
for arg in sys.argv[2:]:
    truth, seed = arg.split(":")
    d = work / f"{truth}_{seed}"
    d.mkdir(parents=True, exist_ok=True)
    path, case = ie.write_effect_record(d, truth, int(seed))
    rec = sj.load_record(path)
    split = D.make_split(rec)
    te = split.test[0]
    h0 = int(np.flatnonzero(te.mask)[0])
    lines = path.read_text().splitlines()
    hdr = [ln for ln in lines if ln and not ln[0].isdigit() and not ln.startswith("-")]
    body = [ln for ln in lines if ln and (ln[0].isdigit() or ln.startswith("-"))]
    (d / "train.csv").write_text("\n".join(hdr + body[:h0]) + "\n")
    out = d / "fit"
    if out.exists():
        import shutil; shutil.rmtree(out)
    t0 = time.time()
    p = subprocess.run([sys.executable, "-m", "smafl_jax", "fit", str(d / "train.csv"), "--out", str(out), "--no-figures"],
                       capture_output=True, text=True, env=dict(os.environ, OPENBLAS_NUM_THREADS="1"))
    if p.returncode:
        print(arg, "FIT FAILED", p.stderr[-400:]); continue
    m = sj.load_model(out / "fit.json")
    yhat = np.asarray(sj.simulate(m, np.asarray(rec.u), float(rec.dt)))
    y = np.asarray(rec.y)
    noise = case["noise_rms_measured"]
    doc = json.loads((out / "fit.json").read_text())
    cls = (doc.get("structure_choice") or {}).get("chosen") or doc.get("model", {}).get("type")
    print(f"{arg} {case['drive']} {case['start']}: smafl fit [{cls}] train {np.sqrt(np.mean((yhat[:h0]-y[:h0])**2))/noise:.2f} "
          f"held-out {np.sqrt(np.mean((yhat[h0:]-y[h0:])**2))/noise:.2f} x noise ({time.time()-t0:.0f} s)", flush=True)
