"""whole_record_ranking on a capture: python naming_probe.py PKL [NAME ...]"""
import sys, pickle
from smafl_jax.diagnosis import whole_record_ranking, whole_record_name
g = pickle.load(open(sys.argv[1], "rb"))
r = whole_record_ranking(g["record"], g["base"], sys.argv[2:] or ["delay"], verbose=True)
noise = g["case"]["noise_rms_measured"]
print(g["truth"], g["seed"], r["base"], {k: round(v / noise, 3) for k, v in r["base_rmse_by_start"].items()}, whole_record_name(r, 0.05), f"{r['seconds']:.0f} s")
