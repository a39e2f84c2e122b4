"""Table of the session-25 output_lag diagnoses: python collect.py LABEL DIR [LABEL DIR ...] (diagnose_independent JSONs)."""
import glob
import json
import sys


def without(r, name="output_lag"):
    """What the calibrated rule would have selected without `name` (approximate: the first other candidate that passes)."""
    if name not in r["selected_new"]:
        return "+".join(r["selected_new"]) or "none"
    rest = [c["name"] for c in r["candidates"] if c["name"] != name and c.get("calibration", {}).get("accepted")]
    return rest[0] if rest else "none"


print("| run | truth | seed | variant | drive, rate, start | effect params | effect / noise | base held-out / noise | selected | ambiguous set | extended held-out / noise | without output_lag | output_lag's decision |")
print("|" + "---|" * 13)
args = sys.argv[1:]
for label, d in zip(args[::2], args[1::2]):
    for f in sorted(glob.glob(f"{d}/*.json")):
        if f.endswith(".partial.json"):
            continue
        for r in json.load(open(f))["rows"]:
            c = r["case"]
            noise = c["noise_rms_measured"]
            ol = next((x for x in r["candidates"] if x["name"] == "output_lag"), {})
            p = ", ".join(f"{k} {v:.3g}" for k, v in (c.get("effect_params") or {}).items() if isinstance(v, (int, float)))
            print(f"| {label} | {r['truth']} | {c['requested_seed']} | {c.get('effect_variant') or ''} | {c['drive']}, "
                  f"{c['rate_hz']:.1f} Hz, {c['start']} | {p} | {c.get('effect_over_noise') or 0:.1f} | "
                  f"{r['base_heldout_over_noise']:.2f} | {'+'.join(r['selected_new']) or 'none'} | "
                  f"{', '.join(r['ambiguous_new'] or []) } | {r['extended_heldout_rmse_new'] / noise:.2f} | {without(r)} | "
                  f"{ol.get('decision', 'n/a').replace('|', chr(92) + '|')} (gain {100 * ol.get('heldout_gain', float('nan')):.1f} %) |")
