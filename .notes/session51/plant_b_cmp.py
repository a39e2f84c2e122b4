import json, sys, numpy as np
old = {json.loads(l)["name"]: json.loads(l) for l in open("/work/main/experiments/results/plant_b_default_fit_session46.jsonl")}
new = {}
for p in sys.argv[1:]:
    for l in open(p):
        r = json.loads(l); new[r["name"]] = r
ho, hn = [], []
for n in sorted(new):
    o, r = old.get(n), new[n]
    if o is None: continue
    def ch(x):
        t = x["cli_stderr_tail"] + x["cli_stdout_tail"]
        i = t.find("model auto -> ")
        return t[i + 14:i + 40].split(":")[0] if i >= 0 else "?"
    ho.append(o["heldout_x_noise"]); hn.append(r["heldout_x_noise"])
    f = "" if abs(np.log(hn[-1] / ho[-1])) < 0.05 else ("BETTER" if hn[-1] < ho[-1] else "WORSE")
    print(f"{n:38s} train {o['train_x_noise']:6.2f} -> {r['train_x_noise']:6.2f} held {ho[-1]:7.2f} -> {hn[-1]:7.2f} {f:6s} {ch(o)} -> {ch(r)}  {o['wall_s']:.0f}s -> {r['wall_s']:.0f}s")
ho, hn = np.array(ho), np.array(hn)
g = lambda h: float(np.exp(np.mean(np.log(h))))
print(f"{len(ho)} records: gm {g(ho):.2f} -> {g(hn):.2f}; within 1.5x {(ho<=1.5).sum()} -> {(hn<=1.5).sum()}; within 3x {(ho<=3).sum()} -> {(hn<=3).sum()}")
