import json, math, sys
rows = [json.loads(l) for f in sys.argv[1:] for l in open(f)]
def gm(v): return math.exp(sum(map(math.log, v)) / len(v))
h = [r["heldout_x_noise"] for r in rows]
print(f"records {len(rows)}: held-out gm {gm(h):.2f}x, within 1.5x {sum(x <= 1.5 for x in h)}, within 3x {sum(x <= 3 for x in h)}, median {sorted(h)[len(h)//2]:.2f}")
tin = [r for r in rows if r["truth"]["heldout_T_inside_fraction"] >= 0.99]
hi = [r["heldout_x_noise"] for r in tin]
print(f"T in range (>= 99 % of held-out T inside training T range): {len(tin)}: gm {gm(hi):.2f}x, within 1.5x {sum(x <= 1.5 for x in hi)}, within 3x {sum(x <= 3 for x in hi)}")
tr = [r.get("train_x_noise") for r in rows]
print("train > 2x noise:", sum(1 for x in tr if x and x > 2), "of", len(rows))
for r in rows:
    print(f"  {r['name']:<36} held {r['heldout_x_noise']:8.2f} train {r.get('train_x_noise', float('nan')):6.2f} T-in {r['truth']['heldout_T_inside_fraction']:.2f} hyst {r['truth']['hysteresis']}")
