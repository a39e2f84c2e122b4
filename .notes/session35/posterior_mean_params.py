"""Fit's nonlinear params replaced by the posterior means; gains re-solved (BVLS+kappa 1 / ridge); held-out error."""
import sys, json, numpy as np, equinox as eqx, jax.numpy as jnp, smafl_jax as sj
D = sys.argv[1]
model, _ = sj.load_model_file(f"{D}/fit/fit.json")
rec = sj.load_record(f"{D}/record.csv"); tr = sj.load_record(f"{D}/train70.csv")
s = json.load(open(f"{D}/{sys.argv[2]}/summary.json"))["parameters"]
n = len(tr); sd = 0.005
def score(m):
    e = np.asarray(sj.simulate(m, rec.u, rec.dt)) - rec.y
    return "train %.2f held %.2f" % (np.sqrt(np.mean(e[:n]**2))/sd, np.sqrt(np.mean(e[n:]**2))/sd)
print("fit", score(model))
m = eqx.tree_at(lambda m: m.thermal.k1, model, jnp.asarray(s["thermal.k1"]["mean"]))
m = eqx.tree_at(lambda m: m.thermal.u0, m, jnp.asarray(s["thermal.u0"]["mean"]))
mem = [s[f"hysteresis.memory[{i}]"]["mean"] for i in range(24)] if "hysteresis.memory[0]" in s else None
if mem: m = eqx.tree_at(lambda m: m.hysteresis.memory, m, jnp.asarray(mem))
print("posterior-mean nonlinear, fit gains", score(m))
for k in (1.0, 0.3):
    print(f"posterior-mean nonlinear, BVLS kappa {k}", score(sj.fit(m, tr, solver=None, init="linear", gain_prior=k).model))
m2 = eqx.tree_at(lambda m: m.thermal.k1, model, jnp.asarray(s["thermal.k1"]["mean"]))
print("only k1 from posterior, BVLS", score(sj.fit(m2, tr, solver=None, init="linear", gain_prior=1.0).model))
print("fit nonlinear, BVLS re-solved", score(sj.fit(model, tr, solver=None, init="linear", gain_prior=1.0).model))
