"""Summarise probe_base.py's rows: per record, the variant the held-out block picks and the one the training BIC picks.

Run: python .notes/session42/probe_summary.py /tmp/s42/probeA.jsonl /tmp/s42/probeB.jsonl
"""
import json
import sys

import numpy as np

rows = [json.loads(line) for p in sys.argv[1:] for line in open(p)]
ratios, clean, lines = [], [], []
for r in sorted(rows, key=lambda r: (r["truth"], r["seed"])):
    h = r["held_over_noise"]
    a, b = h[r["by_held"]], h[r["by_bic"]]
    if r["by_held"] != r["by_bic"]:
        ratios.append(b / a)
        if r["truth"] == "none":
            clean.append(b / a)
    lines.append(f"| {r['truth']} | {r['seed']} | {r['by_held']} | {a:.3f} | {r['by_bic']} | {b:.3f} | {b / a:.3f} |")
print("| truth | seed | held-out picks | held-out / noise | training BIC picks | held-out / noise | ratio |")
print("|---|---|---|---|---|---|---|")
print("\n".join(lines))
q = np.percentile(ratios, [0, 50, 100])
print(f"\n{len(rows)} records; the two rules differ on {len(ratios)}; the BIC pick holds out worse on "
      f"{sum(x > 1 for x in ratios)} of them (ratio min {q[0]:.3f}, median {q[1]:.3f}, max {q[2]:.2f}); "
      f"clean records: differ on {len(clean)} of {sum(r['truth'] == 'none' for r in rows)}, "
      f"median ratio {np.median(clean):.3f}; ratio > 1.2 on {sum(x > 1.2 for x in ratios)}")
