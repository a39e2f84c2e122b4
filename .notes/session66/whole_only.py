"""Whole-record ranking (library `whole_record_ranking`, drive lag re-chosen) of every applicable effect on an
independent record, from the diagnosis's own base (captured as `.notes/session65/capture.py` does).
Run from a tree with experiments/: python whole_only.py TRUTH REQUESTED_SEED"""
import sys, tempfile, time
sys.path.insert(0, "experiments")
import indep_effects as ie
import smafl_jax as sj
from smafl_jax.diagnosis import _diagnose as D
from smafl_jax.diagnosis import whole_record_ranking, whole_record_name
from smafl_jax.identify._metrics import noise_floor
truth, seed = sys.argv[1], int(sys.argv[2])
got = {}
class Done(Exception):
    pass
def patched(m, info, base, cand_start, nm, split, verbose=False):
    got.update(base=base)
    raise Done
D._from_refined_base_too = patched
t0 = time.time()
with tempfile.TemporaryDirectory() as tmp:
    path, case = ie.write_effect_record(tmp, truth, seed)
    rec = sj.load_record(path)
    try:
        D.diagnose(rec, effects=["delay"], refit=False, verbose=False, rule="calibrated", n_null=2, unexplained=False)
    except Done:
        pass
base = got["base"]
names = [n for n in D.applicable_effects(base, D.whole_record_split(rec), D.is_rate_free(rec)) if n != D.NONLOCAL_MEMORY["name"]]
r = whole_record_ranking(rec, base, names)
sd = noise_floor([rec])["sd"]
print(f"{truth} {seed} whole base {r['base_rmse'] / sd:.3f}x est. noise ({r['base']}; by start "
      + ", ".join(f"{k} {v / sd:.3f}" for k, v in r["base_rmse_by_start"].items()) + f") {time.time() - t0:.0f} s")
print("ranked: " + ", ".join(f"{x['name']} {x['gain']:+.3f}" for x in r["ranking"]))
print("name at 0.05:", whole_record_name(r, 0.05), " at 0.10:", whole_record_name(r, 0.10))
