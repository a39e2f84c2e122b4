"""Issue 18: after an excursion above the trained range, how much of the error can any fit remove?

Independent plant (tests/indep_plant.py, plain numpy): a 10-minute record whose held-out 30 % holds
one stretch above the trained drive range (``excursion=True``).  For each seed the script reports,
as RMSE / noise SD over the samples after the plant's hysteresis input is back inside its trained range:

- ``plant shift``: the plant's own output change caused by the excursion (the same record without it,
  same noise-free plant): what a model must predict to recover;
- ``oracle EUPI``: an EUPI with trained thresholds, tilts and fitted memory, fitted on the first 70 %
  against the plant's TRUE hysteresis input (no thermal error at all), before / during / after;
- ``default fit`` (``--default``): `smafl fit` defaults on the voltage record (first 70 %).

If the oracle stays far above 3x after the excursion, the error there is the plant's memory in operators
the training data never moved, which no model fitted on that data can know.

    python experiments/excursion_memory.py [--seeds 11 7 13] [--default] [--out experiments/results/excursion_memory]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT))

import indep_plant as ip  # noqa: E402

import smafl_jax as sj  # noqa: E402
from smafl_jax.report import fit_record  # noqa: E402

KW = dict(drive="multisine", rate_hz=25, start="cold", minutes=10.0)


def _scores(yh, y, sd, h0, sp):
    def e(i, j):
        return float(np.sqrt(np.mean((yh[i:j] - y[i:j]) ** 2)) / sd)

    a = sp["state_end"]
    return {"train": e(0, h0), "before": e(h0, sp["start"]), "during": e(sp["start"], a), "after": e(a, len(y))}


def run_seed(seed, default, tmp):
    r = ip.make_record(seed, excursion=True, **KW)
    r0 = ip.make_record(seed, excursion=False, **KW)
    h0, sd, sp = r["heldout_start"], r["noise_sd"], r["excursion_span"]
    if not sp.get("state_end"):
        return {"seed": seed, "skipped": "the excursion did not take the plant's hysteresis input above its trained range"}
    a = sp["state_end"]
    shift = r["y_clean"][a:] - r0["y_clean"][a:]
    x = ip._core(r["truth"], r["u"], r["dt"], upto="x")["x_h"]  # the plant's true hysteresis input
    t = np.arange(len(x)) * r["dt"]
    p = Path(tmp) / f"x70_{seed}.csv"
    sj.atomic_write_csv(p, {"time_s": t[:h0], "temperature_C": x[:h0], "displacement_mm": r["y"][:h0]})
    m, _, _ = fit_record(
        sj.load_record(p, input="temperature_C", output="displacement_mm"), model="eupi", thresholds=True, tilts=True
    )
    row = {
        "seed": seed,
        "excursion_V": sp["amount_V"],
        "duration_s": (a - sp["start"]) * r["dt"],
        "after_s": (len(x) - a) * r["dt"],
        "plant_shift_x_noise": float(np.sqrt(np.mean(shift**2)) / sd),
        "plant_shift_end_x_noise": float(abs(shift[-1]) / sd),
        "oracle": _scores(np.asarray(sj.simulate(m, x, r["dt"])), r["y"], sd, h0, sp),
    }
    if default:
        p = Path(tmp) / f"u_{seed}.csv"
        ip.write_csv(p, r)
        rec = sj.load_record(p)
        p70 = Path(tmp) / f"u70_{seed}.csv"
        sj.atomic_write_csv(p70, {"time_s": rec.time[:h0], "voltage_V": rec.u[:h0], "displacement_mm": rec.y[:h0]})
        md, _, _ = fit_record(sj.load_record(p70))
        row["default"] = _scores(np.asarray(sj.simulate(md, rec.u, rec.dt)), rec.y, sd, h0, sp)
    return row


def markdown(rows, cmd):
    lines = [
        "# Excursion above the trained range: what the training data can know (issue 18)",
        "",
        f"Command: `{cmd}`. 10-minute multisine records, cold start, 25 Hz; RMSE / noise SD.",
        "",
        "| seed | excursion (V above) | plant's own shift after | oracle EUPI on true input: before / during / after | default fit: before / during / after |",
        "| --- | --- | --- | --- | --- |",
    ]
    for r in rows:
        if "skipped" in r:
            lines.append(f"| {r['seed']} | {r['skipped']} | | | |")
            continue
        o, d = r["oracle"], r.get("default")
        dcell = f"{d['before']:.2f}x / {d['during']:.1f}x / {d['after']:.1f}x" if d else "not run"
        lines.append(
            f"| {r['seed']} | {r['excursion_V']:.2f} | {r['plant_shift_x_noise']:.1f}x (at the end {r['plant_shift_end_x_noise']:.1f}x) | "
            f"{o['before']:.2f}x / {o['during']:.1f}x / {o['after']:.1f}x | {dcell} |"
        )
    return "\n".join(lines) + "\n"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[11, 7, 13])
    ap.add_argument("--default", action="store_true", help="also run the default fit on the voltage record (slow)")
    ap.add_argument("--out", default=str(ROOT / "experiments" / "results" / "excursion_memory"))
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        rows = []
        for s in args.seeds:
            rows.append(run_seed(s, args.default, tmp))
            print(rows[-1], flush=True)
    cmd = "python experiments/excursion_memory.py " + " ".join(argv if argv is not None else sys.argv[1:])
    out = Path(args.out)
    sj.atomic_write_json(out.with_suffix(".json"), {"command": cmd.strip(), "rows": rows})
    sj.atomic_write_text(out.with_suffix(".md"), markdown(rows, cmd.strip()))
    print(f"wrote {out.with_suffix('.json')} and {out.with_suffix('.md')}")


if __name__ == "__main__":
    main()
