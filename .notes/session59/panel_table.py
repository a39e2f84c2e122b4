"""Summary of grid_panel.py rows: per variant geometric mean held out / noise, counts, paired ratio to default."""
import json, math, sys, collections
rows = [json.loads(l) for f in sys.argv[1:] for l in open(f)]
by = collections.defaultdict(dict)
for r in rows:
    by[r["seed"]][r["variant"]] = r
import os
variants = os.environ.get("VARIANTS", "").split(",") if os.environ.get("VARIANTS") else sorted({r["variant"] for r in rows})
seeds = sorted(s for s in by if all(v in by[s] for v in variants))
gm = lambda xs: math.exp(sum(map(math.log, xs)) / len(xs))
print("seed cell | " + " | ".join(f"{v} train/held/val" for v in variants))
for s in seeds:
    print(f"{by[s][variants[0]]['cell']} | " + " | ".join(
        f"{by[s][v]['train']:.2f}/{by[s][v]['held']:.2f}/{by[s][v]['val']:.2f}" for v in variants))
for v in variants:
    h = [by[s][v]["held"] for s in seeds]; t = [by[s][v]["train"] for s in seeds]
    print(f"{v}: n {len(h)} held gm {gm(h):.3f} median {sorted(h)[len(h)//2]:.2f} <=1.5x {sum(x <= 1.5 for x in h)} <=3x {sum(x <= 3 for x in h)} worst {max(h):.1f} | train gm {gm(t):.3f} <=1.2x {sum(x <= 1.2 for x in t)}")
    if v != "default" and "default" in variants:
        rat = [by[s][v]["held"] / by[s]["default"]["held"] for s in seeds]
        print(f"   vs default: held ratio gm {gm(rat):.3f}, better >10% {sum(x < 0.9 for x in rat)}, worse >10% {sum(x > 1.1 for x in rat)}")
