"""Default fits on plant D (experiments/indep_plant_d.py): the thermal physics the toolkit's cascade lacks.

Each record's first 70 % is fitted with `fit_record` defaults (= `smafl fit REC`); the saved (whole-training-part)
model is simulated from t = 0 over the whole record and scored on the last 30 %: RMSE over the noise SD against the
noisy output, and against the clean output (``clean_x``: what is left of the model's own error).  ``--physics`` keeps
only the named elements (ablation: which one a fit cannot absorb); ``--model`` fits one class instead of auto.

    python experiments/fit_plant_d.py OUT.jsonl --seeds 1 2 3 [--cells pwm:25:cold:displacement ...]
        [--physics sleeve convection ...] [--model cascade] [--minutes 15]
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "experiments"))
sys.path.insert(0, str(ROOT))

import indep_plant_d as pd  # noqa: E402

CELLS = ("pwm:25:cold:displacement", "multisine:10:warm:length", "steps:5:mid:displacement", "triangle:50:cold:length")


def run_one(seed, cell, physics, model, minutes, tmp, slow_mode=None):
    import smafl_jax as sj
    from smafl_jax.report import fit_record

    drive, rate, start, sensor = cell.split(":")
    r = pd.make_record(seed, drive=drive, rate_hz=float(rate), minutes=minutes, start=start, sensor=sensor, physics=physics)
    h0, sd = r["heldout_start"], r["noise_sd"]
    path = pd.write_csv(Path(tmp) / f"d{seed}_{drive}.csv", r, stop=h0)
    t0 = time.perf_counter()
    opts = {**({"model": model} if model else {}), **({"slow_mode": slow_mode} if slow_mode is not None else {})}
    m, doc, _ = fit_record(sj.load_record(path), **opts)
    secs = time.perf_counter() - t0
    yh = np.asarray(sj.simulate(m, r["voltage"], 1.0 / float(rate)))
    e = yh - r["output"]
    ec = yh - r["output_clean"]
    choice = (doc.get("settings") or {}).get("structure_choice") or {}
    # the saved model without its input hold (`hold_input`): what the hold changed on the held-out part
    h = sj.hysteresis_of(m)
    free = m.with_hysteresis(h.with_held(None)) if getattr(h, "held", None) is not None else m
    e_free = np.asarray(sj.simulate(free, r["voltage"], 1.0 / float(rate))) - r["output"]
    return {
        "seed": seed,
        "cell": cell,
        "physics": list(physics),
        "model": model or "auto",
        "chosen": choice.get("chosen", doc.get("model", {}).get("structure") if isinstance(doc.get("model"), dict) else None),
        "train_x": float(np.sqrt(np.mean(e[:h0] ** 2)) / sd),
        "held_x": float(np.sqrt(np.mean(e[h0:] ** 2)) / sd),
        "clean_x": float(np.sqrt(np.mean(ec[h0:] ** 2)) / sd),
        "hold_input": (doc.get("settings") or {}).get("hold_input"),
        "held_x_not_held": float(np.sqrt(np.mean(e_free[h0:] ** 2)) / sd),
        "whole_record_check": choice.get("whole_record_check"),
        "slow_mode_check": choice.get("slow_mode_check"),
        "slow_mode": slow_mode,
        "thermal": {k: float(getattr(th, k)) for k in ("k1", "slow_k1", "slow_ratio") if getattr(th, k) is not None}
        if (th := sj.thermal_of(m) if hasattr(sj, "thermal_of") else getattr(m, "thermal", None)) is not None
        else None,
        "seconds": secs,
        "truth": {k: v for k, v in r["truth"].items() if k not in ("temperature", "fraction")},
    }


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--cells", nargs="+", default=list(CELLS))
    ap.add_argument("--physics", nargs="*", default=list(pd.PHYSICS))
    ap.add_argument("--model", default=None)
    ap.add_argument("--minutes", type=float, default=15.0)
    ap.add_argument("--slow-mode", default=None, help="fit_record's slow_mode (default: its own default)")
    a = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        for seed in a.seeds:
            for cell in a.cells:
                row = run_one(seed, cell, tuple(a.physics), a.model, a.minutes, tmp, a.slow_mode)
                with open(a.out, "a") as fh:
                    fh.write(json.dumps(row) + "\n")
                print(
                    f"s{seed} {cell:28s} {row['model']:10s} chosen {row['chosen']}: train {row['train_x']:.2f}x held "
                    f"{row['held_x']:.2f}x (clean {row['clean_x']:.2f}x) {row['seconds']:.0f} s",
                    flush=True,
                )


if __name__ == "__main__":
    main()
