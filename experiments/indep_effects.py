"""Independent effect records for the blind-diagnosis benchmark (issue 13): plain numpy, no smafl_jax.

Built on the independent plant `tests/indep_plant.py` (drive -> Joule heating -> first-order thermal
lag -> play-operator hysteresis with off-grid thresholds/tilts, random initial memory and polynomial
-> sensor noise + 16-bit quantisation), which already carries each effect in its own physical form.
This module fixes WHICH physical form stands for each catalogue name, draws every parameter from a
seed, keeps records short (2000-4000 samples) and checks that every effect changes the clean output
by >= 5x the noise RMS (measured here on the record itself: std of y_clean(with) - y_clean(without),
same drive, same structure).

Cases (truth name -> plant effect / allowed variants, constraint):
    none                -> no effect
    resistance_tc       -> R rising with temperature: R = R0 (1 + a1 dT) (a1 > 0) or + a2 dT^2 (a2 > 0)
    asymmetric_cooling  -> cooling slower/faster than heating (constant ratio) or latent heat on cooling
    ambient_drift       -> linear ramp of the room temperature or slow exponential warming of the room
    nonlinear_cooling   -> natural convection: loss ~ theta^1.25 (k1 [(1 - c) + c (theta / theta_ref)^0.25] theta)
    rate_dependence     -> play thresholds widen with the (filtered) rate of the hysteresis input
    creep               -> one Kelvin-Voigt element or a spectrum of 3-5 time constants on the output
    delay               -> transport delay of the drive (whole samples) or fractional delay of the output
    output_lag          -> the output sensor's lag (the plant's sensor_lag): one first-order pole or two equal ones

Starts are "cold" (ambient, drive on from t = 0) or "warm" (steady state at the first drive level), drives
are drawn from the plant's FAMILIES, noise is the plant's (5 um fixed or 0.1-1.5 % of the stroke).

Run:  python experiments/indep_effects.py --out /tmp/indep_records [--seed 0]   (writes CSV + .truth.json)
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
import indep_plant as ip  # noqa: E402  (plain numpy; shares no code with smafl_jax)

#: truth name -> (plant effect name, allowed variants, constraint on the drawn base parameters)
CASES: dict[str, tuple[str | None, tuple[str, ...], object]] = {
    "none": (None, (), None),
    "resistance_tc": (
        "resistance_tc",
        ("linear", "quadratic"),
        lambda p, v: (p["a1_per_K"] > 0) if v == "linear" else (p["a2_per_K2"] > 0 and p["a1_per_K"] >= 0),
    ),
    "asymmetric_cooling": ("asymmetric_cooling", ("constant_ratio", "latent_heat"), None),
    "ambient_drift": ("ambient_drift", ("linear_ramp", "room_warming"), None),
    "nonlinear_cooling": ("nonlinear_cooling", ("convective",), lambda p, v: abs(p["exponent"] - 0.25) < 1e-12),
    "rate_dependence": ("rate_dependence", ("threshold_widening",), None),
    "creep": ("creep", ("kelvin_voigt", "spectrum"), None),
    "delay": ("delay", ("integer", "fractional"), None),
    "output_lag": ("sensor_lag", ("first_order", "second_order"), None),
}
#: Effects in no catalogue of the toolkit (tests/indep_plant.py UNCATALOGUED): the right answer of a diagnosis is no
#: catalogue name, and its "unexplained" report should find structure left and name the correlate behind it.
UNCATALOGUED_CASES: dict[str, tuple[str, tuple[str, ...], object]] = {
    name: (name, variants, None) for name, variants in ip.UNCATALOGUED.items()
}
#: What the unexplained report should name as the strongest correlate, per uncatalogued truth and variant (None: no
#: correlate of the toolkit's list carries it; structure left is then the right answer).
EXPECTED_CORRELATE = {
    ("extra_column", "humidity"): "humidity_pct",
    ("extra_column", "supply_voltage"): "supply_V",
    ("periodic_disturbance", "sinusoid"): None,
    ("periodic_disturbance", "square_load"): None,
    ("gain_drift", "linear"): "elapsed_time",
    ("gain_drift", "warmup"): "elapsed_time",
}
TRUTHS = tuple(CASES)
UNCATALOGUED_TRUTHS = tuple(UNCATALOGUED_CASES)
#: every truth; a record's seed offset is its index here (the catalogued truths keep theirs)
ALL_TRUTHS = TRUTHS + UNCATALOGUED_TRUTHS
CASES = {**CASES, **UNCATALOGUED_CASES}
MIN_SAMPLES, MAX_SAMPLES = 2000, 4000
SNR_MIN = ip.EFFECT_MIN_SNR  # 5x the noise RMS


def _draw_options(seed: int, name: str) -> dict:
    """Record-level choices (drive family, sample rate, length, start, variant) from the seed."""
    rng = np.random.default_rng([int(seed), 77])
    n = int(rng.integers(MIN_SAMPLES + 500, MAX_SAMPLES - 500))
    rate = math.exp(rng.uniform(math.log(2.0), math.log(10.0)))  # 0.1 .. 0.5 s: thermal time constants 5 .. 50 s
    variants = CASES[name][1]
    return {
        "drive": str(rng.choice(ip.FAMILIES)),
        "rate_hz": rate,
        "minutes": n / rate / 60.0,
        "start": str(rng.choice(["cold", "warm"])),
        "noise": str(rng.choice(ip.NOISE_KINDS)),
        "variant": str(rng.choice(variants)) if variants else None,
    }


def _constraint_ok(name: str, seed: int, opts: dict) -> bool:
    effect, _, check = CASES[name]
    if effect is None or check is None:
        return True
    # random_truth with make_record's own generator: the same structure make_record will draw
    truth = ip.random_truth(
        np.random.default_rng([int(seed), 1]), effect=effect, variant=opts["variant"], start=opts["start"], noise=opts["noise"]
    )
    return bool(check(truth["effect"]["params"], opts["variant"]))


def make_effect_record(name: str, seed: int, max_tries: int = 50) -> dict:
    """One record of truth ``name``: the plant record (ip.make_record) plus ``case`` and the measured effect size.

    Seeds whose draw violates the case's constraint (e.g. a falling resistance) are skipped deterministically
    (seed, seed + 7919, ...); the seed actually used is in ``case['plant_seed']``.
    """
    if name not in CASES:
        raise ValueError(f"unknown truth {name!r}; choose one of {ALL_TRUTHS}")
    effect = CASES[name][0]
    for i in range(max_tries):
        s = int(seed) + 7919 * i
        opts = _draw_options(s, name)
        if _constraint_ok(name, s, opts):
            break
    else:
        raise RuntimeError(f"no seed near {seed} satisfies the constraint of {name}")
    rec = ip.make_record(
        s,
        effect=effect,
        variant=opts["variant"],
        drive=opts["drive"],
        rate_hz=opts["rate_hz"],
        minutes=opts["minutes"],
        start=opts["start"],
        noise=opts["noise"],
    )
    case = {"truth": name, "requested_seed": int(seed), "plant_seed": s, **opts, "n": len(rec["y"])}
    sd = float(rec["noise_sd"])
    # measured noise RMS (noise + quantisation) and the effect's size on this very record
    case["noise_sd"] = sd
    case["noise_rms_measured"] = float(np.sqrt(np.mean((rec["y"] - rec["y_clean"]) ** 2)))
    if effect is not None:
        clean = dict(rec["truth"])
        clean["effect"] = None
        y0 = ip._core(clean, rec["u"], rec["dt"])["y_clean"]
        delta = rec["y_clean"] - y0
        case["effect_delta_std"] = float(np.std(delta))
        case["effect_delta_max"] = float(np.max(np.abs(delta - np.mean(delta))))
        case["effect_over_noise"] = case["effect_delta_std"] / case["noise_rms_measured"]
        case["effect_over_noise_ok"] = bool(case["effect_over_noise"] >= SNR_MIN)
        case["effect_params"] = ip._py(ip._effect_params(rec["truth"]["effect"]))
        case["effect_variant"] = rec["truth"]["effect"]["variant"]
    rec["case"] = case
    return rec


def write_effect_record(folder, name: str, seed: int) -> tuple[Path, dict]:
    """Write the record as ``folder/NAME_sSEED.csv`` (+ ``.truth.json`` with ``case``); returns (path, case)."""
    rec = make_effect_record(name, seed)
    path = ip.write_csv(Path(folder) / f"{name}_s{seed}.csv", rec)
    tp = ip.truth_path(path)
    doc = json.loads(tp.read_text())
    doc["case"] = rec["case"]
    ip._atomic_write_text(tp, json.dumps(ip._py(doc), indent=1))
    return path, rec["case"]


def diagnosis_start(folder, name: str, seed: int):
    """The diagnosis' own start on one record: ``(record, case, split, screened start, variable-projection base)``,
    as `smafl_jax.diagnose` builds them (shared by the oracle and candidate-start experiments)."""
    import smafl_jax as sj
    from smafl_jax.diagnosis import choose_base, fit_extended, make_split, screened_base

    path, case = write_effect_record(folder, name, seed)
    rec = sj.load_record(path)
    split = make_split(rec)
    screened, _ = screened_base(choose_base(rec)[0], split)
    return rec, case, split, screened, fit_extended(screened, [], split)[0]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True, help="folder for the CSV records")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--truths", nargs="*", default=list(TRUTHS))
    a = ap.parse_args(argv)
    for k, name in enumerate(a.truths):
        path, c = write_effect_record(a.out, name, a.seed + 1000 * k)
        snr = c.get("effect_over_noise")
        print(
            f"{name:>20s}: {path.name} n={c['n']} dt={1 / c['rate_hz']:.3f} s drive={c['drive']} start={c['start']} "
            f"noise={c['noise_rms_measured']:.4g} mm"
            + ("" if snr is None else f" effect/noise={snr:.1f} ({c['effect_variant']})")
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
