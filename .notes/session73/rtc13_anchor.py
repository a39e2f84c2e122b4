import pickle, sys, numpy as np
import smafl_jax as sj
from smafl_jax.diagnosis import _diagnose as D
from smafl_jax.effects import catalogue as C
d = pickle.load(open(sys.argv[1], 'rb'))
b, split = d.base, d.split
def run(tag):
    m, info = D.fit_extended(b, ["resistance_tc"], split)
    m2 = D.refine_model(m, split)
    for t, mm in (("varpro", m), ("refined", m2)):
        e = mm.effects[0]
        print(tag, t, "beta %.4g" % float(e.beta), "train sse %.4f held %.5f (base %.5f)" % (
            D._train_sse(mm, split.train), D._held(mm, split)["rmse"], D._held(b, split)["rmse"]), flush=True)
if sys.argv[2] == "plain":
    run("plain")
    sys.exit()
C.ResistanceTC.heating = lambda self, heat, q, q_ref: heat * (1.0 + self.beta) / (1.0 + (self.beta / q_ref) * np.maximum(q, 0.0)) if False else heat * (1.0 + self.beta) / (1.0 + (self.beta / q_ref) * __import__("jax").numpy.maximum(q, 0.0))
run("anchored")
