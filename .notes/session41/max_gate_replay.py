"""Replay of the diagnosis max-error gate with a slack of 0.5 x the candidate's held-out RMSE on the stored session-31
independent diagnoses (experiments/results/diagnose_independent_session31): which candidates the slack would let on."""
import glob
import json

for f in sorted(glob.glob("experiments/results/diagnose_independent_session31/*.json")):
    for r in json.load(open(f))["rows"]:
        for c in r.get("candidates", []):
            cal = c.get("calibration") or {}
            if cal.get("gates", {}).get("max_error") is False:
                m, rm = cal["heldout_max_abs_error"], c["heldout_rmse"]
                print(f"{r['truth']:20s} {c['name']:20s} gain {cal['gain']:.3f} max {m['before']:.4g}->{m['after']:.4g} "
                      f"passes with slack: {m['after'] <= m['before'] + 0.5 * rm}")
