import sys, json, subprocess, os
sys.path.insert(0, "/work/main/tests")
import indep_plant as ip
from pathlib import Path
out = Path("/tmp/s33/length"); out.mkdir(exist_ok=True)
csvs = []
for j, (drive, rate, minutes, start) in enumerate([("pwm", 25, 8, "cold"), ("multisine", 50, 5, "warm")]):
    r = ip.make_record(31, drive=drive, rate_hz=rate, minutes=minutes, start=start, orientation="length")
    p = out / f"l{j}_{drive}_{start}.csv"; ip.write_csv(p, r); csvs.append(str(p)); noise = r["noise_sd"]
code = "import sys; sys.path.insert(0, sys.argv.pop(1)); from smafl_jax.cli import main; sys.exit(main())"
for root, tag in ((sys.argv[1], sys.argv[2]),):
    o = out / f"o_{tag}"
    subprocess.run([sys.executable, "-c", code, root, "fit", *csvs, "--model", "cascade", "--no-figures", "--out", str(o)], capture_output=True, env={**os.environ, "OPENBLAS_NUM_THREADS": "1"})
    d = json.loads((o / "fit.json").read_text())
    print(tag, "train x %.2f" % (d["metrics"]["train"]["rmse"] / noise), "LORO x %.2f" % (d["metrics"]["validation"]["rmse"] / noise), [round(f["model"]["rmse"] / noise, 2) for f in d["validation"]["folds"]], "orientation", d["model"]["hysteresis"].get("orientation"), [ (r.get("u0_V"), r.get("memory")) for r in d.get("per_record_start") or []])
