"""Re-anchoring fitted models on a calibration segment of an unseen run, on the shared real records (issue 14).

Run:  OPENBLAS_NUM_THREADS=1 python experiments/recalibrate_real.py [--data ../shared/data/real]
      [--out experiments/results/recalibrate_real]   -> recalibrate_real.json + recalibrate_real.md
Data are read in place (never copied): sources in /work/shared/data/README.md.

(a) NiTi wire, temperature_front_C -> length_signal.  Leave-one-record-out inside each family (electric
    01-05, water steps 01-04): one joint EUPI (`fit_records(model="eupi", split="none", max_steps=30)`,
    i.e. what `smafl fit A.csv B.csv ... --model eupi --split none --max-steps 30` fits) on the other
    records of the family; the held-out record is simulated from its own first sample (the model's
    descended rule) raw, and re-anchored (`recalibrate`) on its first 10 % or 20 %.
(b) SMA wing reversal branches (FORC), voltage_V -> displacement.  A "second set" is emulated by holding
    out every other reversal branch (odd labels, then even labels; the major loop, branch 0, always trains).
    Models: `fit_record(model="preisach")` and `fit_record(model="auto")` (= plain `smafl fit`; a cascade),
    `split="none"`, `max_steps=30`, on the training branches.  The held-out branches, back to back, are the
    new run; the calibration segment is its first rising curve (0 V up to the first reversal voltage).
    Also a planted drift on the held-out run (recorded voltage 0.1 V low and 3 % short, displacement
    +0.5): real data with a known drift, to show what the calibration recovers when there is one.
Every score counts only the samples after the segment (raw and re-anchored on the same samples):
RMSE and e_r (eq. 3, range of the measured output after the segment).  A model-free floor for (b): each
held-out descending branch interpolated from its two trained neighbours (experiments/forc_preisach_cv.py).
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "experiments"))

FIT_SETS = {
    "all three": ("input_gain", "input_offset", "output_offset"),
    "input+output offset": ("input_offset", "output_offset"),
    "output offset": ("output_offset",),
}
MAX_STEPS = 30
PLANTED = {"input_gain": 1.03, "input_offset": 0.1, "output_offset": 0.5}


def _rebased(rec):
    import dataclasses

    return dataclasses.replace(rec, time=np.arange(len(rec)) * rec.dt)


def _score(model, rec, segment, fit):
    """Raw and re-anchored metrics after ``segment`` (a slice of samples) of ``rec``."""
    from smafl_jax import recalibrate, simulate
    from smafl_jax.identify import after_segment_metrics

    t = time.perf_counter()
    cal, info = recalibrate(model, rec.u, rec.y, rec.dt, segment, fit=fit)
    s = after_segment_metrics(rec.y, simulate(model, rec.u, rec.dt), simulate(cal, rec.u, rec.dt), info["scored_from_sample"])
    return {
        "fit": list(fit),
        "segment_samples": [info["segment"]["start_sample"], info["segment"]["end_sample"]],
        "scored_from_s": info["scored_from_s"],
        "input_gain": info["input_gain"],
        "input_offset": info["input_offset"],
        "output_offset": info["output_offset"],
        "segment_rmse_before": info["segment_rmse_before"],
        "segment_rmse_after": info["segment_rmse_after"],
        "raw": s["raw"],
        "recalibrated": s["recalibrated"],
        "seconds": time.perf_counter() - t,
    }


def niti(data: Path, log):
    from smafl_jax import load_record
    from smafl_jax.identify import fit_records

    rows = []
    families = {
        "electric": [f"niti_wire_electric_0{i}.csv" for i in range(1, 6)],
        "water_step": [f"niti_wire_water_step_0{i}.csv" for i in range(1, 5)],
    }
    for fam, files in families.items():
        recs = [load_record(data / f, input="temperature_front_C", output="length_signal") for f in files]
        for j, held in enumerate(recs):
            t = time.perf_counter()
            model, _, _ = fit_records([r for i, r in enumerate(recs) if i != j], model="eupi", split="none", max_steps=MAX_STEPS)
            fit_s = time.perf_counter() - t
            for frac in (0.1, 0.2):
                seg = slice(0, int(round(frac * len(held))))
                for label, names in FIT_SETS.items():
                    r = _score(model, held, seg, names)
                    rows.append(
                        {"family": fam, "heldout": files[j], "segment": f"first {int(frac * 100)} %", "fit_set": label, **r}
                    )
                    log(
                        f"{fam} {files[j]} first {int(frac * 100)} % {label:>20s}: raw RMSE {r['raw']['rmse']:.3f} e_r "
                        f"{r['raw']['e_r_percent']:.1f} % -> RMSE {r['recalibrated']['rmse']:.3f} e_r "
                        f"{r['recalibrated']['e_r_percent']:.1f} % (g {r['input_gain']:.3f}, a {r['input_offset']:.3g}, "
                        f"c {r['output_offset']:.3g}); fit {fit_s:.0f} s"
                    )
    return rows


def _first_rise(rec) -> slice:
    """Samples of the first rising curve: from the start to the first reversal (the first maximum of the input)."""
    b = np.asarray(rec.extra["branch"]).astype(int)
    first = b == b[0]
    k = int(np.argmax(np.where(first, rec.u, -np.inf)))
    return slice(0, k + 1)


def forc(data: Path, log):
    from forc_preisach_cv import neighbour_interpolation

    from smafl_jax import load_record, metrics
    from smafl_jax.report import fit_record

    rec = load_record(data / "sma_wing_forc_train.csv")
    b = np.asarray(rec.extra["branch"]).astype(int)
    rows, floors = [], []
    for name, held_labels in (("odd branches held out", [1, 3, 5, 7, 9]), ("even branches held out", [2, 4, 6, 8, 10])):
        train = rec.take(~np.isin(b, held_labels))
        new = _rebased(rec.take(np.isin(b, held_labels)))
        seg = _first_rise(new)
        # model-free floor on the same samples after the segment
        per_branch = {lab: rec.take(b == lab) for lab in np.unique(b)}
        trained = [per_branch[lab] for lab in np.unique(b) if lab not in held_labels]
        interp = np.concatenate([neighbour_interpolation(trained, per_branch[lab]) for lab in held_labels])
        floor = metrics(new.y[seg.stop :], interp[seg.stop :])
        floors.append({"split": name, "heldout_branches": held_labels, "interpolation_after_segment": floor})
        log(
            f"FORC {name}: model-free interpolation after the first rise: RMSE {floor['rmse']:.3f}, e_r {floor['e_r_percent']:.1f} %"
        )
        drifted = _planted_drift(new)
        for model_name in ("preisach", "auto"):
            t = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)  # fit_record's empty-validation means with split none
                model, doc, _ = fit_record(train, model=model_name, split="none", max_steps=MAX_STEPS)
            fit_s = time.perf_counter() - t
            for run_name, run in (("held-out branches", new), ("held-out branches + planted drift", drifted)):
                for label, names in FIT_SETS.items():
                    r = _score(model, run, seg, names)
                    rows.append(
                        {
                            "split": name,
                            "heldout_branches": held_labels,
                            "model": f"{model_name} ({type(model).__name__})",
                            "run": run_name,
                            "segment": f"first rising curve ({seg.stop} samples, 0 -> {float(np.max(new.u[seg])):.2f} V)",
                            "fit_set": label,
                            **r,
                        }
                    )
                    log(
                        f"FORC {name} {model_name:>8s} {run_name:>34s} {label:>20s}: raw RMSE {r['raw']['rmse']:.3f} e_r "
                        f"{r['raw']['e_r_percent']:.1f} % -> RMSE {r['recalibrated']['rmse']:.3f} e_r "
                        f"{r['recalibrated']['e_r_percent']:.1f} % (g {r['input_gain']:.3f}, a {r['input_offset']:.3g}, "
                        f"c {r['output_offset']:.3g}); fit {fit_s:.0f} s"
                    )
    return rows, floors


def _planted_drift(rec):
    """The same run seen through a drifted rig: recorded u = (u_true - a) / g, recorded y = y_true + c."""
    import dataclasses

    g, a, c = PLANTED["input_gain"], PLANTED["input_offset"], PLANTED["output_offset"]
    return dataclasses.replace(rec, u=(rec.u - a) / g, y=rec.y + c)


NOTES = """## Reading

- Default bounds of `recalibrate` (gain within x1.5, input offset within 25 % of the record's input span) were added after
  a first, unbounded run of this script: on the NiTi records the segment fit then found gains of 0.04-0.11 and input
  offsets of -125 to +93 degC (e.g. electric 03, first 20 %: gain 0.106, offset -125, output offset 277) that matched the
  segment and wrecked the rest of the run. Bounded, several NiTi fits still end at a bound (`at_bound`, warned): the
  first 10-20 % of a NiTi run (rest, then one heating ramp) does not determine an input gain and offset.
- NiTi: the joint EUPI does not carry to an unseen run (raw e_r 44-135 %, electric 04 with its thermocouple spikes far
  worse), and re-anchoring on the start of the run does not repair that: the error is not a constant drift but the
  model's shape and start state (a run that starts at 14 degC, water 02, is the clearest: the offset that fits its cold
  start is wrong for the rest). Re-anchoring makes most NiTi records worse after the segment; it is not a fix there.
- SMA FORC: inside one file the held-out branches carry no drift, so the calibration has nothing to correct (the first
  rising curve is the major loop that trained the model) and changes the held-out error by a few hundredths. With a
  planted drift (a voltage reading 0.1 V low and 3 % short, displacement +0.5) the raw error rises to 35 % and the
  three-parameter re-anchoring on the first rising curve brings the Preisach model back to its no-drift error
  (5.5 % / 6.6 % e_r), recovering the planted numbers within 0.03 (gain 1.034 / 1.042, input offset 0.089 / 0.072,
  output offset 0.508 / 0.504); the output offset alone cannot (26 %).
- The held-back second set itself is not available here, so the goal (below 8 % e_r with calibration on it) cannot be
  judged; on the emulated second sets the Preisach model is at 5.5-6.9 % e_r with or without calibration, the plain
  `smafl fit` cascade at 16-22 %.
"""


def _md(doc) -> str:
    lines = [
        "# Re-anchoring on a calibration segment of an unseen run (issue 14)",
        "",
        f"Command: `{doc['command']}` ({doc['seconds']:.0f} s wall on the shared 2-core machine; "
        f"fits with max_steps={MAX_STEPS}). Data read in place from /work/shared/data/real (sources in its README).",
        "",
        "Scores count only the samples after the calibration segment, for the raw and the re-anchored model alike. "
        "e_r = eq. 3 over those samples (max |error| / measured range, %).",
        "",
        "## (a) NiTi, leave-one-record-out inside each family (joint EUPI on the others)",
        "",
        "| family | held out | segment | fitted | raw RMSE | raw e_r % | re-anchored RMSE | re-anchored e_r % | gain | input offset | output offset |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in doc["niti"]:
        lines.append(
            f"| {r['family']} | {r['heldout']} | {r['segment']} | {r['fit_set']} | {r['raw']['rmse']:.3f} | "
            f"{r['raw']['e_r_percent']:.1f} | {r['recalibrated']['rmse']:.3f} | {r['recalibrated']['e_r_percent']:.1f} | "
            f"{r['input_gain']:.3f} | {r['input_offset']:.3g} | {r['output_offset']:.3g} |"
        )
    lines += ["", "Medians over held-out records (RMSE ratio re-anchored / raw; e_r):", ""]
    for key, s in doc["niti_summary"].items():
        lines.append(
            f"- {key}: median RMSE ratio {s['median_rmse_ratio']:.2f} (better on {s['n_better']}/{s['n']}), "
            f"median e_r {s['median_e_r_raw']:.1f} % -> {s['median_e_r_recalibrated']:.1f} %"
        )
    lines += [
        "",
        "## (b) SMA wing FORC: every other branch held out as an emulated second set",
        "",
        "| split | model-free interpolation RMSE | e_r % |",
        "|---|---|---|",
    ]
    for f in doc["forc_floor"]:
        m = f["interpolation_after_segment"]
        lines.append(f"| {f['split']} | {m['rmse']:.3f} | {m['e_r_percent']:.1f} |")
    lines += [
        "",
        "| split | model | run | fitted | raw RMSE | raw e_r % | re-anchored RMSE | re-anchored e_r % | gain | input offset | output offset |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in doc["forc"]:
        lines.append(
            f"| {r['split']} | {r['model']} | {r['run']} | {r['fit_set']} | {r['raw']['rmse']:.3f} | "
            f"{r['raw']['e_r_percent']:.1f} | {r['recalibrated']['rmse']:.3f} | {r['recalibrated']['e_r_percent']:.1f} | "
            f"{r['input_gain']:.3f} | {r['input_offset']:.3g} | {r['output_offset']:.3g} |"
        )
    lines += [
        "",
        f"Planted drift: recorded voltage = (true - {PLANTED['input_offset']}) / {PLANTED['input_gain']}, "
        f"recorded displacement = true + {PLANTED['output_offset']} (so the exact re-anchoring is gain "
        f"{PLANTED['input_gain']}, input offset {PLANTED['input_offset']}, output offset {PLANTED['output_offset']}).",
        "",
    ]
    return "\n".join(lines) + "\n" + NOTES


def _summary(rows):
    out = {}
    keys = sorted({(r["family"], r["segment"], r["fit_set"]) for r in rows})
    for fam, seg, fs in keys:
        sel = [r for r in rows if (r["family"], r["segment"], r["fit_set"]) == (fam, seg, fs)]
        ratio = [r["recalibrated"]["rmse"] / r["raw"]["rmse"] for r in sel]
        out[f"{fam}, {seg}, {fs}"] = {
            "n": len(sel),
            "median_rmse_ratio": float(np.median(ratio)),
            "n_better": int(sum(x < 1 for x in ratio)),
            "median_e_r_raw": float(np.median([r["raw"]["e_r_percent"] for r in sel])),
            "median_e_r_recalibrated": float(np.median([r["recalibrated"]["e_r_percent"] for r in sel])),
        }
    return out


def main(argv=None):
    from smafl_jax import atomic_write_json, atomic_write_text

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=str(ROOT.parent / "shared" / "data" / "real"))
    ap.add_argument("--out", default=str(ROOT / "experiments" / "results" / "recalibrate_real"))
    ap.add_argument("--only", choices=("niti", "forc"), default=None)
    ap.add_argument("--md-only", action="store_true", help="re-write the .md from the existing .json (no fitting)")
    a = ap.parse_args(argv)
    if a.md_only:
        import json

        out = Path(a.out)
        atomic_write_text(out.with_suffix(".md"), _md(json.loads(out.with_suffix(".json").read_text())))
        return
    t0 = time.perf_counter()

    def log(msg):
        print(msg, file=sys.stderr, flush=True)

    data = Path(a.data)
    doc = {"command": "OPENBLAS_NUM_THREADS=1 python experiments/recalibrate_real.py" + (f" --only {a.only}" if a.only else "")}
    if a.only in (None, "niti"):
        doc["niti"] = niti(data, log)
        doc["niti_summary"] = _summary(doc["niti"])
    if a.only in (None, "forc"):
        doc["forc"], doc["forc_floor"] = forc(data, log)
    doc["seconds"] = time.perf_counter() - t0
    doc["planted_drift"] = PLANTED
    doc["max_steps"] = MAX_STEPS
    out = Path(a.out)
    atomic_write_json(out.with_suffix(".json"), doc)
    if a.only is None:
        atomic_write_text(out.with_suffix(".md"), _md(doc))
    log(f"done in {doc['seconds']:.0f} s")


if __name__ == "__main__":
    main()
