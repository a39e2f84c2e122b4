import sys, tempfile
sys.path.insert(0, "experiments")
import indep_effects as ie, smafl_jax as sj
from smafl_jax.data import split as S
recs = [("rate_dependence",5011),("output_lag",8013),("creep",6012),("creep",6013),("creep",6014),("ambient_drift",3010),("resistance_tc",1012),("nonlinear_cooling",4012),("asymmetric_cooling",2013),("asymmetric_cooling",2012),("rate_dependence",5014),("none",45),("delay",7011),("output_lag",8010)]
with tempfile.TemporaryDirectory() as tmp:
    for t, s in recs:
        p, case = ie.write_effect_record(tmp, t, s)
        r = sj.load_record(p)
        tb = S.time_block(r); il = S.interleaved(r)
        print(t, s, case["drive"], len(r), "time %.2f" % S.coverage(tb)["covered_fraction"], "interleaved %.2f" % S.coverage(il)["covered_fraction"], il.test_labels)
