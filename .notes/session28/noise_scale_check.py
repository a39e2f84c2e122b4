"""How close is the data checks' noise scale (1.4826 MAD of second differences / sqrt 6) to the independent plant's
true output noise SD, by drive family, rate and start?  (session 28; no fitting)"""
import sys

import numpy as np

sys.path.insert(0, "/work/main/tests")
import indep_plant as ip  # noqa: E402

from smafl_jax.data.checks import noise_scale  # noqa: E402

rows = []
for fam in ip.FAMILIES:
    for rate in (5.0, 10.0, 25.0, 100.0):
        for seed in range(6):
            r = ip.make_record(100 + seed, drive=fam, rate_hz=rate, minutes=5.0 if rate > 20 else 10.0)
            est = noise_scale(r["y"])
            rows.append((fam, rate, seed, est / r["noise_sd"], r["truth"]["noise"]["kind"], r["truth"]["sensor"]["lsb_mm"] / r["noise_sd"] if r["truth"]["sensor"].get("lsb_mm") else 0))
for fam in ip.FAMILIES:
    for rate in (5.0, 10.0, 25.0, 100.0):
        q = np.array([x[3] for x in rows if x[0] == fam and x[1] == rate])
        print(f"{fam:14s} {rate:5.0f} Hz  ratio est/true: median {np.median(q):.2f} min {q.min():.2f} max {q.max():.2f}")
q = np.array([x[3] for x in rows])
print("all", len(q), "median", np.median(q), "within 0.8-1.25:", np.mean((q > 0.8) & (q < 1.25)), "within 0.67-1.5:", np.mean((q > 0.67) & (q < 1.5)))
