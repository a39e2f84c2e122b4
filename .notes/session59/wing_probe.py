"""Which structure auto keeps on the SMA wing FORC record, and each candidate's validation RMSE (one code root).

python .notes/session59/wing_probe.py ROOT
"""
import sys, json
sys.path.insert(0, sys.argv[1])
import smafl_jax as sj
from smafl_jax.report import fit_record
rec = sj.load_record("/work/shared/data/real/sma_wing_forc_train.csv")
m, doc, _ = fit_record(rec)
sc = doc["settings"].get("structure_choice") or {}
print(sj.__file__, sc.get("chosen"), [(c["structure"], (c["validation"] or {}).get("rmse"), c.get("train_rmse")) for c in sc.get("candidates", [])])
print([n for n in doc["notes"] if "memory" in n or "split" in n][:4])
