"""Print the error trace of a probe_record.py result in 40 blocks (session 48)."""
import json
import sys

import numpy as np

d = np.load(sys.argv[1])
u, y, yh, yc, h0, sd, xh, dt = d["u"], d["y"], d["yh"], d["y_clean"], int(d["h0"]), float(d["sd"]), d["x_h"], float(d["dt"])
e = (yh - y) / sd
n = len(u)
b = n // 40
for k in range(0, n, b):
    s = slice(k, k + b)
    print(f"t={k * dt:7.1f} u={u[s].mean():5.2f} [{u[s].min():4.2f},{u[s].max():4.2f}] x_h={xh[s].mean():5.3f} y={yc[s].mean():7.3f} "
          f"err={e[s].mean():7.2f} rms={np.sqrt((e[s] ** 2).mean()):6.2f} {'HELD' if k >= h0 else ''}")
doc = json.load(open(sys.argv[1].replace(".npz", "_doc.json")))
for line in doc["notes"]:
    if "memory" in line or "screening" in line or "auto" in line[:12]:
        print("-", line[:400])
