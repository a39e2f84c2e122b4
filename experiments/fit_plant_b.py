"""Default `smafl fit` on records of the second independent plant (experiments/indep_plant_b.py).

Each record's first 70 % is written to a CSV and fitted exactly as a user would (the CLI in a subprocess,
defaults, one BLAS thread); the saved fit.json is then simulated over the WHOLE record from t = 0 with the
public API and scored on the last 30 % (RMSE / noise SD against the noisy and the clean output, e_r = max|err| /
clean output range).  Two plain-numpy baselines fitted on the same 70 % are scored on the same 30 %: a static
cubic of the voltage and a first-order lag (k by grid, of V^2 or V, the better on the training part) then a cubic.

    python experiments/fit_plant_b.py [--smoke] [--seeds 1 2 3] [--work /tmp/plant_b_fits] [--jsonl OUT.jsonl]
    python experiments/fit_plant_b.py --plot NAME [NAME ...]   # prediction vs measured, T vs output

Results: experiments/results/plant_b_default_fit.jsonl (one line per record, appended as each finishes) and .md;
``--jsonl OUT.jsonl`` gives a new sweep its own file (and OUT.md), e.g. the session-46 fresh seeds 22-23.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from scipy.signal import lfilter

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(Path(__file__).resolve().parent))

import indep_plant_b as pb  # noqa: E402

RESULTS = ROOT / "experiments" / "results"
JSONL = RESULTS / "plant_b_default_fit.jsonl"
MD = RESULTS / "plant_b_default_fit.md"
#: the `smafl` of the interpreter running this script (its venv), so the fits use the same install
SMAFL = str(Path(sys.executable).with_name("smafl"))
GRID_DRIVES = ("pwm", "multisine", "steps", "triangle")
GRID_RATES = (5, 25, 100)


def grid(seeds: list[int], minutes: float) -> list[dict]:
    """Seeds x drives x rates; start and sensor rotate deterministically over the grid."""
    cells = []
    for s in seeds:
        for d, drive in enumerate(GRID_DRIVES):
            for ri, rate in enumerate(GRID_RATES):
                cells.append(
                    dict(
                        seed=s,
                        drive=drive,
                        rate_hz=rate,
                        start=pb.STARTS[(s + d + ri) % 3],
                        sensor=pb.SENSORS[(s + d // 2 + ri) % 2],
                        minutes=minutes,
                        noise_sd=0.005,
                    )
                )
    # a few noisier records
    cells += [
        dict(seed=11, drive="steps", rate_hz=25, start="warm", sensor="length", minutes=minutes, noise_sd=0.02),
        dict(seed=12, drive="triangle", rate_hz=5, start="cold", sensor="displacement", minutes=minutes, noise_sd=0.02),
        dict(seed=13, drive="staircase", rate_hz=25, start="mid", sensor="displacement", minutes=minutes, noise_sd=0.02),
    ]
    return cells


def name_of(c: dict) -> str:
    return f"s{c['seed']}_{c['drive']}_{c['rate_hz']}hz_{c['start']}_{c['sensor'][:4]}_n{c['noise_sd']:g}"


def rmse(e: np.ndarray) -> float:
    return float(np.sqrt(np.mean(e**2)))


def cubic(x: np.ndarray) -> np.ndarray:
    return np.column_stack([np.ones_like(x), x, x**2, x**3])


def baselines(u: np.ndarray, y: np.ndarray, dt: float, h0: int) -> dict:
    """Static cubic of V, and a first-order lag (k grid, of V^2 or V) then a cubic, both fitted on [:h0]."""
    out = {}
    coef, *_ = np.linalg.lstsq(cubic(u[:h0]), y[:h0], rcond=None)
    out["static_cubic"] = cubic(u) @ coef
    best = None
    for src_name, src in (("V2", u**2), ("V", u)):
        for k in np.geomspace(1e-3, 5.0, 80):
            a = np.exp(-k * dt)
            # x[n+1] = a x[n] + (1 - a) src[n], started at rest with the first input
            x, _ = lfilter([0.0, 1.0 - a], [1.0, -a], src, zi=[a * src[0]])
            scale = max(np.ptp(x[:h0]), 1e-12)
            xs = x / scale
            c, *_ = np.linalg.lstsq(cubic(xs[:h0]), y[:h0], rcond=None)
            pred = cubic(xs) @ c
            sse = float(np.sum((pred[:h0] - y[:h0]) ** 2))
            if best is None or sse < best[0]:
                best = (sse, pred, src_name, float(k))
    out["lag_cubic"] = best[1]
    out["lag_cubic_info"] = {"source": best[2], "k": best[3]}
    return out


def pick(doc: dict, *keys, default=None):
    """doc[k1][k2]... or default."""
    cur = doc
    for k in keys:
        if not isinstance(cur, dict) or k not in cur:
            return default
        cur = cur[k]
    return cur


def fit_summary(doc: dict) -> dict:
    """What fit.json says about the fit (keys read defensively: the format may move)."""
    model = doc.get("model", {})
    hy = model.get("hysteresis", model)
    th = model.get("thermal", {})
    settings = doc.get("settings", {})
    sign = hy.get("orientation", model.get("orientation"))
    base = pick(doc, "baselines", "models", default={}) or {}
    return {
        "model_type": model.get("type"),
        "structure": settings.get("structure"),
        "structure_choice": settings.get("structure_choice"),
        "sees": model.get("sees"),
        "orientation": {1: "rises", -1: "falls"}.get(sign, sign),
        "hysteresis_type": hy.get("type"),
        "thermal_init": th.get("init"),
        "u0": th.get("u0"),
        "k1": th.get("k1"),
        "tau_fit_s": 1.0 / th["k1"] if th.get("k1") else None,
        "memory_used": settings.get("memory_used"),
        "train_rmse": pick(doc, "metrics", "train", "rmse"),
        "val_rmse": pick(doc, "metrics", "validation", "rmse"),
        "baseline_val_rmse": {k: pick(v, "heldout", "rmse") for k, v in base.items()},
        "baseline_verdict": pick(doc, "baselines", "verdict"),
        "coverage": pick(doc, "split", "coverage", "covered_fraction"),
        "notes": doc.get("notes"),
        "data_check_findings": pick(doc, "data_checks", "n_findings"),
        "solver": {k: pick(doc, "solver", k) for k in ("n_steps", "converged", "message", "seconds", "refinement")},
    }


def subsample(rec: dict, every: int) -> dict:
    """Every `every`-th sample of a record (a probe: the same plant run seen at a lower rate, same split time)."""
    out = dict(rec)
    for k in ("time", "voltage", "output", "output_clean"):
        out[k] = rec[k][::every]
    out["truth"] = dict(
        rec["truth"], temperature=rec["truth"]["temperature"][::every], fraction=rec["truth"]["fraction"][::every]
    )
    out["heldout_start"] = -(-rec["heldout_start"] // every)
    return out


def run_one(c: dict, work: Path, extra: tuple[str, ...] = (), every: int = 1, linear_thermal: bool = False) -> dict:
    import smafl_jax as sj

    name = name_of(c) + (f"_every{every}" if every > 1 else "") + "".join(f"_{a.strip('-')}" for a in extra)
    name += "_linear_thermal" if linear_thermal else ""
    d = work / name
    d.mkdir(parents=True, exist_ok=True)
    kw = {k: v for k, v in c.items() if k != "seed"}
    rec = pb.make_record(c["seed"], **kw, linear_thermal=linear_thermal)
    if every > 1:
        rec = subsample(rec, every)
    h0 = rec["heldout_start"]
    csv = pb.write_csv(d / "first70.csv", rec, stop=h0)
    pb.write_csv(d / "full.csv", rec)
    out = d / "fit"
    if out.exists():  # a rerun: start from an empty folder (the CLI refuses to overwrite)
        import shutil

        shutil.rmtree(out)
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", MKL_NUM_THREADS="1")
    cmd = [SMAFL, "fit", str(csv), "--out", str(out), "--no-figures", *extra]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    (d / "stdout.txt").write_text(proc.stdout)
    (d / "stderr.txt").write_text(proc.stderr)
    tr = rec["truth"]
    row = {
        "name": name,
        "cell": c,
        "extra_args": list(extra),
        "every": every,
        "linear_thermal": linear_thermal,
        "wall_s": wall,
        "returncode": proc.returncode,
        "truth": {
            "hysteresis": tr["hysteresis"]["class"],
            "tau_s": tr["thermal"]["tau_s"],
            "radiative": tr["thermal"]["eps"] > 0,
            "orientation": tr["orientation"],
            "start": tr["start"],
            "sensor_lag_s": tr["sensor_lag_s"],
            "stroke_mm": tr["stroke_mm"],
            "fraction_range": [float(tr["fraction"].min()), float(tr["fraction"].max())],
            "T_range": [float(tr["temperature"].min()), float(tr["temperature"].max())],
            "heldout_T_inside_fraction": tr["heldout_T_inside_fraction"],
            "heldout_clipped_samples": tr["heldout_clipped_samples"],
        },
        "cli_warnings": [ln for ln in (proc.stdout + proc.stderr).splitlines() if "warn" in ln.lower()],
        "cli_stdout_tail": proc.stdout[-1500:],
        "cli_stderr_tail": proc.stderr[-1500:],
    }
    y, yc, u = rec["output"], rec["output_clean"], rec["voltage"]
    dt = every / c["rate_hz"]
    sd = rec["noise_sd"]
    rng_y = float(np.ptp(yc))
    base = baselines(u, y, dt, h0)
    row["baselines_x_noise"] = {k: rmse(base[k][h0:] - y[h0:]) / sd for k in ("static_cubic", "lag_cubic")}
    row["baselines_train_x_noise"] = {k: rmse(base[k][:h0] - y[:h0]) / sd for k in ("static_cubic", "lag_cubic")}
    row["lag_cubic_info"] = base["lag_cubic_info"]
    fit_json = out / "fit.json"
    if proc.returncode != 0 or not fit_json.exists():
        row["crashed"] = True
        print(f"{name}: CLI FAILED rc={proc.returncode} ({wall:.0f} s): {proc.stderr[-300:]}", flush=True)
        return row
    doc = json.loads(fit_json.read_text())
    row["fit"] = fit_summary(doc)
    model = sj.load_model(fit_json)
    yhat = np.asarray(sj.simulate(model, u, dt))
    np.savez(d / "pred.npz", yhat=yhat, y=y, yc=yc, u=u, T=tr["temperature"], h0=h0)
    err = yhat - y
    row.update(
        crashed=False,
        train_x_noise=rmse(err[:h0]) / sd,
        heldout_x_noise=rmse(err[h0:]) / sd,
        heldout_clean_x_noise=rmse(yhat[h0:] - yc[h0:]) / sd,
        heldout_e_r=float(np.max(np.abs(yhat[h0:] - yc[h0:])) / rng_y),
        output_range_mm=rng_y,
    )
    print(
        f"{name} [{tr['hysteresis']['class']}, tau {tr['thermal']['tau_s']:.0f} s]: held-out {row['heldout_x_noise']:.2f}x noise "
        f"(clean {row['heldout_clean_x_noise']:.2f}x, e_r {100 * row['heldout_e_r']:.1f} %), train {row['train_x_noise']:.2f}x; "
        f"static cubic {row['baselines_x_noise']['static_cubic']:.2f}x, lag+cubic {row['baselines_x_noise']['lag_cubic']:.2f}x; "
        f"orientation {row['fit']['orientation']} (truth {tr['orientation']}); {wall:.0f} s",
        flush=True,
    )
    return row


def verdict(r: dict) -> str:
    if r.get("crashed"):
        return "CRASH"
    bad = []
    if r["heldout_x_noise"] > 3.0:
        bad.append(">3x noise")
    if r["heldout_x_noise"] > min(r["baselines_x_noise"].values()):
        bad.append("worse than baseline")
    if r["fit"].get("orientation") not in (None, r["truth"]["orientation"]):
        bad.append("wrong orientation")
    return ", ".join(bad) or "ok"


def markdown(rows: list[dict], cmd: str, probes: bool = True) -> str:
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True).stdout.strip()
    except OSError:
        commit = "?"
    lines = [
        "# Default `smafl fit` on the second independent plant (experiments/indep_plant_b.py)",
        "",
        f"Command: `{cmd}` (commit {commit}); each fit: `OPENBLAS_NUM_THREADS=1 smafl fit FIRST70.csv --out DIR --no-figures`.",
        "Scores on the last 30 % of each record, simulated from t = 0 with the saved fit.json (`load_model` + `simulate`).",
        "held = held-out RMSE / noise SD (noisy output); clean = against the noise-free output; e_r = max|err| / clean output range.",
        "Baselines fitted on the same first 70 % (plain numpy): static cubic of V; first-order lag (k by grid) then a cubic.",
        "T-in = fraction of held-out samples whose plant temperature lies inside the first 70 %'s range.",
        "",
        "| record | hyst | tau s | T-in | held | clean | e_r % | train | static | lag+cubic | orient (truth) | thermal/memory | val RMSE mm | wall s | verdict |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        t = r["truth"]
        b = r["baselines_x_noise"]
        if r.get("crashed"):
            lines.append(
                f"| {r['name']} | {t['hysteresis']} | {t['tau_s']:.0f} | {t['heldout_T_inside_fraction']:.2f} | - | - | - | - | "
                f"{b['static_cubic']:.2f} | {b['lag_cubic']:.2f} | - | - | - | {r['wall_s']:.0f} | CRASH |"
            )
            continue
        f = r["fit"]
        val = f["val_rmse"]
        val = f"{val:.4f}" if isinstance(val, float) else str(val)
        lines.append(
            f"| {r['name']} | {t['hysteresis']} | {t['tau_s']:.0f} | {t['heldout_T_inside_fraction']:.2f} | {r['heldout_x_noise']:.2f} | "
            f"{r['heldout_clean_x_noise']:.2f} | {100 * r['heldout_e_r']:.1f} | {r['train_x_noise']:.2f} | {b['static_cubic']:.2f} | "
            f"{b['lag_cubic']:.2f} | {f['orientation']} ({t['orientation']}) | {f['thermal_init']}/{f['memory_used']} | {val} | {r['wall_s']:.0f} | {verdict(r)} |"
        )
    ok = [r for r in rows if not r.get("crashed")]
    if ok:
        gm = float(np.exp(np.mean([np.log(r["heldout_x_noise"]) for r in ok])))
        lines += ["", f"Records: {len(rows)}; crashed {len(rows) - len(ok)}; held-out geometric mean {gm:.2f}x noise; "
                  f"failures (>3x noise, worse than a baseline, wrong orientation, crash): {sum(verdict(r) != 'ok' for r in rows)}."]  # fmt: skip
    probes = RESULTS / "plant_b_probes.jsonl" if probes else None  # the session-19 probes belong to its table only
    if probes is not None and probes.exists():
        lines += [
            "",
            "## Probes (one record refitted with one change; `--only NAME --probe-args '...'` or `--every N`)",
            "",
            "| probe | extra fit options | every | linear thermal plant | held | train | orient (truth) | wall s |",
            "|---|---|---|---|---|---|---|---|",
        ]
        for line in probes.read_text().splitlines():
            r = json.loads(line)
            if r.get("crashed"):
                lines.append(
                    f"| {r['name']} | {' '.join(r['extra_args'])} | {r['every']} | {r.get('linear_thermal', False)} | crash | - | - | {r['wall_s']:.0f} |"
                )
                continue
            lines.append(
                f"| {r['name']} | {' '.join(r['extra_args']) or '-'} | {r['every']} | {r.get('linear_thermal', False)} | {r['heldout_x_noise']:.2f} | {r['train_x_noise']:.2f} | "
                f"{r['fit']['orientation']} ({r['truth']['orientation']}) | {r['wall_s']:.0f} |"
            )
    return "\n".join(lines) + "\n"


def plot(names: list[str], work: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    for name in names:
        z = np.load(work / name / "pred.npz")
        h0 = int(z["h0"])
        fig, ax = plt.subplots(1, 3, figsize=(16, 4.5))
        t = np.arange(z["y"].size)
        ax[0].plot(t, z["y"], lw=0.5, label="measured")
        ax[0].plot(t, z["yhat"], lw=0.7, label="smafl fit")
        ax[0].axvline(h0, color="k", ls="--")
        ax[0].legend()
        ax[0].set(title=name, xlabel="sample")
        ax[1].plot(t, z["yhat"] - z["y"], lw=0.5)
        ax[1].axvline(h0, color="k", ls="--")
        ax[1].set(title="error (mm)")
        ax[2].plot(z["T"][:h0], z["y"][:h0], lw=0.4, label="measured, first 70 %")
        ax[2].plot(z["T"][h0:], z["y"][h0:], lw=0.4, label="measured, held-out")
        ax[2].plot(z["T"], z["yhat"], lw=0.4, label="model")
        ax[2].set(xlabel="plant T (C)", title="T vs output")
        ax[2].legend(fontsize=7)
        fig.tight_layout()
        p = work / f"{name}.png"
        fig.savefig(p, dpi=80)
        plt.close(fig)
        print(p)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument("--minutes", type=float, default=10.0)
    ap.add_argument("--smoke", action="store_true", help="two low-rate records only; results go to the work folder")
    ap.add_argument("--work", type=Path, default=Path("/tmp/plant_b_fits"))
    ap.add_argument("--plot", nargs="+", default=None)
    ap.add_argument("--only", nargs="+", default=None, help="record names to run")
    ap.add_argument("--probe-args", default="", help="probe: extra `smafl fit` options, e.g. '--orientation rises'")
    ap.add_argument("--every", type=int, default=1, help="probe: keep every N-th sample of the record")
    ap.add_argument("--linear-thermal", action="store_true", help="probe: the same record from a linear thermal plant")
    ap.add_argument("--jsonl", type=Path, default=None, help="results file of the sweep (default: the session-19 one)")
    args = ap.parse_args()
    if args.plot:
        plot(args.plot, args.work)
        return
    cells = grid(args.seeds, args.minutes)
    if args.only:
        cells = [c for c in cells if name_of(c) in args.only]
    if args.smoke:
        cells = [c for c in cells if c["rate_hz"] <= 25][:2]
    extra = tuple(args.probe_args.split())
    probe = bool(extra) or args.every > 1 or args.linear_thermal
    jsonl = args.work / "smoke.jsonl" if args.smoke else (RESULTS / "plant_b_probes.jsonl" if probe else args.jsonl or JSONL)
    args.work.mkdir(parents=True, exist_ok=True)
    done = set()
    rows = []
    if jsonl.exists():
        for line in jsonl.read_text().splitlines():
            r = json.loads(line)
            done.add(r["name"])
            rows.append(r)
    if probe:  # probes are appended to their own file; the table is the sweep's
        for c in cells:
            row = run_one(c, args.work, extra, args.every, args.linear_thermal)
            with open(jsonl, "a") as fh:
                fh.write(json.dumps(row, default=float) + "\n")
        return
    for i, c in enumerate(cells):
        if name_of(c) in done:
            print(f"[{i + 1}/{len(cells)}] {name_of(c)}: already in {jsonl.name}, skipped", flush=True)
            continue
        print(f"[{i + 1}/{len(cells)}] {name_of(c)} ...", flush=True)
        row = run_one(c, args.work)
        rows.append(row)
        with open(jsonl, "a") as fh:  # appended per record so a partial run is kept
            fh.write(json.dumps(row, default=float) + "\n")
    cmd = "python experiments/fit_plant_b.py " + " ".join(sys.argv[1:])
    text = markdown(rows, cmd, probes=args.jsonl is None)
    target = args.work / "smoke.md" if args.smoke else (args.jsonl.with_suffix(".md") if args.jsonl else MD)
    tmp = target.with_suffix(".md.tmp")
    tmp.write_text(text)
    os.replace(tmp, target)
    print(text)


if __name__ == "__main__":
    main()
