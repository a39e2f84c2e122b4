import sys
sys.path.insert(0, sys.argv[1])
import smafl_jax as sj
from smafl_jax.models import _thermal
orig = _thermal.JouleThermal.settles_within
def spy(self, dt, k1=None, samples=1.0):
    r = orig(self, dt, k1, samples)
    print("SETTLES", dt, float(self.k1), k1, r, flush=True)
    return r
_thermal.JouleThermal.settles_within = spy
from smafl_jax.report import fit_record
rec = sj.load_record("/work/shared/data/real/sma_wing_forc_train.csv")
m, doc, _ = fit_record(rec)
sc = doc["settings"].get("structure_choice") or {}
print(sc.get("chosen"), [(c["structure"], (c["validation"] or {}).get("rmse")) for c in sc.get("candidates", [])])
