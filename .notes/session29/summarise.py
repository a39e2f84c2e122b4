"""Session 29: off vs prod (per-operator memory search) from patched_fit.jsonl rows.  python summarise.py FILE.jsonl"""
import collections, json, math, sys
rows = collections.defaultdict(dict)
for line in open(sys.argv[1]):
    r = json.loads(line)
    rows[(r["seed"], r["cell"])][r["mode"]] = r
pairs = [(k, v) for k, v in sorted(rows.items(), key=lambda kv: (kv[0][1], kv[0][0])) if "off" in v and "prod" in v]
print("| record | seed | off: train | off: held-out | search: train | search: held-out | s off / search |")
print("|---|---|---|---|---|---|---|")
for (seed, cell), v in pairs:
    a, b = v["off"], v["prod"]
    print(f"| {cell} | {seed} | {a['train']:.2f}x | {a['held']:.2f}x | {b['train']:.2f}x | {b['held']:.2f}x | {a['seconds']:.0f} / {b['seconds']:.0f} |")
for mode in ("off", "prod"):
    h = [v[mode]["held"] for _, v in pairs]
    t = [v[mode]["train"] for _, v in pairs]
    gm = math.exp(sum(map(math.log, h)) / len(h))
    print(f"{mode}: {len(h)} records, held-out gm {gm:.3f}, within 1.5x {sum(x <= 1.5 for x in h)}, within 3x {sum(x <= 3 for x in h)}; "
          f"train gm {math.exp(sum(map(math.log, t)) / len(t)):.3f}, train within 1.5x {sum(x <= 1.5 for x in t)}")
