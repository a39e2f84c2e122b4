"""Capture the diagnosis's base, candidate start, joint candidate and split for a record.
python capture.py TRUTH SEED OUT.pkl [NAME]"""
import sys, tempfile, pickle
sys.path.insert(0, "experiments")
import indep_effects as ie
import smafl_jax as sj
from smafl_jax.diagnosis import _diagnose as D
truth, seed, out = sys.argv[1], int(sys.argv[2]), sys.argv[3]
name = sys.argv[4] if len(sys.argv) > 4 else (truth if truth != "none" else "delay")
name = {"output_lag": "output_lag"}.get(name, name)
got = {}
class Done(Exception):
    pass
orig = D._from_refined_base_too
def patched(m, info, base, cand_start, nm, split, verbose=False):
    got.update(start=cand_start, base=base, split=split, cand_profiled=m)
    o = orig(m, info, base, cand_start, nm, split, verbose)
    got['joint'] = o[0]
    raise Done
D._from_refined_base_too = patched
with tempfile.TemporaryDirectory() as tmp:
    path, case = ie.write_effect_record(tmp, truth, seed)
    rec = sj.load_record(path)
    try:
        D.diagnose(rec, effects=[name], refit=False, verbose=False, rule="calibrated", n_null=2, unexplained=False)
    except Done:
        pass
got.update(case=case, name=name, truth=truth, seed=seed, record=rec)
pickle.dump(got, open(out, "wb"))
print("saved", out)
