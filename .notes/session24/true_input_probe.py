"""Where does G's cascade lose on plant B (linear-thermal twins, Preisach truth)?
 mode "T":   the static Gaussian Preisach (`preisach-gauss`) fitted on the plant's TRUE temperature (first 70 %)
 mode "k1":  the G cascade with the screening's k1 grid replaced by the plant's true k1 (1/tau), then as default
 mode "def": the G cascade, defaults (as thermal_ablation.py)
Scored on the whole record simulated from t=0: RMSE/noise on the first 70 % (train_x) and the last 30 % (held_x).
    python true_input_probe.py MODE SEEDS RATES OUT.jsonl"""
import json, os, sys, time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path[:0] = [str(ROOT / "experiments"), str(ROOT / "tests")]


def job(args):
    mode, c = args
    os.environ["OPENBLAS_NUM_THREADS"] = "1"
    import fit_plant_b as fb
    import indep_plant_b as pb
    import smafl_jax as sj
    from smafl_jax.identify import _choose  # private: pin the screening's k1 grid (probe only)

    r = pb.make_record(c["seed"], **{k: v for k, v in c.items() if k != "seed"}, linear_thermal=True)
    tr = r["truth"]
    row = {"name": fb.name_of(c), "mode": mode, "truth": tr["hysteresis"]["class"], "T_inside": tr["heldout_T_inside"],
           "lag": tr["sensor_lag_s"], "k1_true": tr["thermal"]["k1"]}
    if row["truth"] != "preisach":
        return None
    h0, dt = r["heldout_start"], 1.0 / c["rate_hz"]
    u = tr["temperature"] if mode.startswith("T") else r["voltage"]
    rec = sj.Record.from_arrays(r["time"][:h0], u[:h0], r["output"][:h0], input_name="temperature_C" if mode.startswith("T") else "voltage_V",
                                output_name="displacement_mm")
    if mode.startswith("T_ext"):  # the grid widened beyond the training range by EXT of it at each end
        sj.GaussianPreisach.EXTEND = float(os.environ.get("EXT", "0.25"))
    if mode == "k1":
        orig = _choose._profiled
        _choose._profiled = lambda m, d, w, g: orig(m, d, w, np.array([tr["thermal"]["k1"]]))
    t0 = time.time()
    model = "preisach-gauss" if mode.startswith("T") else "cascade-preisach-gauss"
    from smafl_jax.report import fit_record
    m, doc, _ = fit_record(rec, model=model)
    row["wall"] = time.time() - t0
    yh = np.asarray(sj.simulate(m, u, dt))
    e = yh - r["output"]
    row["train_x"] = float(np.sqrt(np.mean(e[:h0] ** 2)) / r["noise_sd"])
    row["held_x"] = float(np.sqrt(np.mean(e[h0:] ** 2)) / r["noise_sd"])
    th = getattr(m, "thermal", None)
    if th is not None:
        row["k1_fit"] = float(th.k1)
    print(json.dumps(row), flush=True)
    return row


if __name__ == "__main__":
    import fit_plant_b as fb
    mode, seeds, rates, out = sys.argv[1], [int(s) for s in sys.argv[2].split()], [float(x) for x in sys.argv[3].split()], sys.argv[4]
    cells = [c for c in fb.grid(seeds, 10.0) if c["rate_hz"] in rates]
    with ProcessPoolExecutor(int(os.environ.get("WORKERS", "2"))) as ex:
        for row in ex.map(job, [(mode, c) for c in cells]):
            if row:
                with open(out, "a") as f:
                    f.write(json.dumps(row) + "\n")
