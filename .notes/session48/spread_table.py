"""The fit's memory_spread against the held-out figure, matrix rows of session 48 (and session 47's for the same records)."""
import glob
import json
import sys

old = {(r["seed"], r["cell"]): r for p in glob.glob("experiments/results/class_rule_session47/matrix_fresh_*_rule_prescreen.json")
       for r in json.load(open(p))}
rows = [r for p in sys.argv[1:] for r in json.load(open(p))]
print("| record | seed | kept class | held out | spread (noise SD) | warned |\n|---|---|---|---|---|---|")
same = 0
for r in rows:
    sp = r.get("memory_spread") or {}
    q = sp.get("rms_ratio")
    same += abs(old[(r["seed"], r["cell"])]["held"] - r["held"]) <= 1e-3 * r["held"]
    print(f"| {r['cell']} | {r['seed']} | {r['chosen']} | {r['held']:.2f} | {'-' if q is None else f'{q:.2f}'} | "
          f"{'yes' if q is not None and q > 3 else ''} |")
bad = [r for r in rows if r["held"] > 2]
good = [r for r in rows if r["held"] <= 2]
warn = lambda r: (r.get("memory_spread") or {}).get("rms_ratio") is not None and r["memory_spread"]["rms_ratio"] > 3
print(f"\n{len(rows)} records ({same} with the same held-out figure as session 47's rows): held out above 2x {len(bad)}, "
      f"warned {sum(map(warn, bad))}; at or below 2x {len(good)}, warned {sum(map(warn, good))}; "
      f"no spread (no fitted-memory candidate or a Preisach class kept) {sum(not r.get('memory_spread') for r in rows)}")
