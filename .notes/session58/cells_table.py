"""Table of random-cell rows (base_fit_before_after.py outputs): held-out/noise, class, memory."""
import json, glob, sys, math
rows = []
for f in sorted(glob.glob(sys.argv[1] + "/s*.json")):
    try:
        r = json.load(open(f))
    except ValueError:
        continue
    r = r[0] if isinstance(r, list) else r
    rows.append(r)
    sp = r.get("memory_spread") or {}
    print(f"{r['seed']} | {r['cell']} | {r['train']:.2f} | {r['held']:.2f} | {r.get('val', float('nan')):.2f} | {r['chosen']} | {r.get('memory')} | spread {sp.get('rms_ratio', float('nan')):.2f} | {r['seconds']:.0f} s")
h = [r["held"] for r in rows]
print(f"n {len(h)} gm {math.exp(sum(map(math.log, h)) / len(h)):.2f} within 1.5x {sum(x <= 1.5 for x in h)} within 3x {sum(x <= 3 for x in h)} worst {max(h):.2f}")
