"""Session 29: the default fit (fit_record, --model auto) of a plant-A random_levels record with and without a per-operator
search of the fitted operator memory after the uniform starts (monkeypatched into identify._choose._screen_memory).
python patched_fit.py SEED CELL MINUTES on|off [class]"""
import json, sys, time
import numpy as np
sys.path.insert(0, "/work/main/tests")
import indep_plant as ip
import jax.numpy as jnp
import smafl_jax as sj
from smafl_jax.identify import _choose  # private: experiment patches the memory screening
from smafl_jax.identify._fit import _bvls  # private: the fit's BVLS
from smafl_jax.report import fit_record

seed, cell, minutes, mode = int(sys.argv[1]), sys.argv[2], float(sys.argv[3]), sys.argv[4]
cls = sys.argv[5] if len(sys.argv) > 5 else "auto"
CELLS = {"cold": dict(drive="random_levels", rate_hz=20, start="cold", orientation="length"),
         "warm": dict(drive="random_levels", rate_hz=10, start="warm")}
CELLS.update({f"m{i}": v for i, v in enumerate(ip.MATRIX_CELLS.values())})
kw = CELLS[cell]
FR = np.linspace(0.0, 1.0, 11)

def play_cols(s, r_, a_, y0):
    F = np.array(y0, float); out = np.empty((len(s), len(r_)))
    for k, sk in enumerate(s):
        F = np.maximum(sk - r_, np.minimum(a_ * (sk + r_), F)); out[k] = F
    return out

def search(model, data, weights, sweeps=2):
    (u, y, d), = data
    w = np.asarray(weights[0]); keep = w > 0; sw = np.sqrt(w[keep])
    h = model.hysteresis
    x = np.asarray(model.hysteresis_input(jnp.asarray(u), d))
    s = np.asarray(h.normalise(jnp.asarray(x)))
    rr, aa = (np.asarray(v) for v in h._bank())
    lo0, up0 = s[0] - rr, aa * (s[0] + rr)
    n = len(rr)
    cand = np.stack([play_cols(s, rr, aa, lo0 + f * (up0 - lo0)) for f in FR])[:, keep] * sw[None, :, None]
    base = np.asarray(model.features(jnp.asarray(u), d))[keep] * sw[:, None]
    b = y[keep] * sw
    nonneg = h.nonnegative_columns(); sign = float(h.orientation)
    f0 = 1 / (1 + np.exp(-np.asarray(h.memory)))
    k_of = np.array([int(np.argmin(np.abs(FR - f))) for f in f0])
    def design(k_of):
        A = base.copy(); A[:, 1:1 + n] = sign * cand[k_of, :, np.arange(n)].T; return A
    best = _bvls(design(k_of), b, nonneg)[1]
    start = best
    for sweep in range(sweeps):
        for i in range(n):
            for k in range(len(FR)):
                if k == k_of[i]: continue
                kk = k_of.copy(); kk[i] = k
                loss = _bvls(design(kk), b, nonneg)[1]
                if loss < best - 1e-12:
                    best = loss; k_of = kk
    f = np.clip(FR[k_of], 0.01, 0.99)
    print(f"  memory search: loss {start:.6g} -> {best:.6g}", flush=True)
    from smafl_jax.identify._fit import init_linear
    import dataclasses
    m = model.with_hysteresis(dataclasses.replace(h, memory=jnp.asarray(np.log(f / (1 - f)))))
    return init_linear(m, data, weights=weights), best

orig = _choose._screen_memory
def patched(model, data, weights, loss, info, table, say, row):
    model, loss, info = orig(model, data, weights, loss, info, table, say, row)
    if type(model.hysteresis).__name__ == "EUPI" and model.hysteresis.init == "fitted" and len(data) == 1:
        t0 = time.time()
        m2, l2 = search(model, data, weights)
        print(f"  search took {time.time() - t0:.1f} s", flush=True)
        if l2 < loss:
            return m2, l2, {**info, "memory_start": "searched"}
    return model, loss, info
def patched2(model, data, weights, loss, info, table, say, row):
    from smafl_jax.identify._memory_search import search_memory  # private: the production search
    model, loss, info = orig(model, data, weights, loss, info, table, say, row)
    if type(model.hysteresis).__name__ != "EUPI" or len(data) != 1 or not hasattr(model, "thermal"):
        return model, loss, info
    u_hi = float(np.max(data[0][0]))
    for it in range(3):
        got = search_memory(model, data, weights)
        if got is None or got[1] >= loss:
            break
        model, loss = got
        print(f"  search {it}: loss {loss:.6g} k1 {float(model.thermal.k1):.4g} u0 {model.thermal.u0}", flush=True)
        if model.thermal.init == "given":
            l2, m2, _ = _choose.refine_thermal_start(model, data, weights, u_hi)
            if l2 < loss:
                model, loss = m2, l2
                print(f"  thermal: loss {loss:.6g} k1 {float(model.thermal.k1):.4g} u0 {float(model.thermal.u0):.4g}", flush=True)
    return model, loss, {**info, "memory_start": "searched"}
_choose.MEMORY_SEARCH = mode == "prod"  # the production search (identify._memory_search) on or off
if mode == "on":
    _choose._screen_memory = patched
if mode == "on2":
    _choose._screen_memory = patched2

r = ip.make_record(seed, minutes=minutes, **kw)
h0, sd = r["heldout_start"], r["noise_sd"]
from pathlib import Path
p = Path(f"/tmp/s29/pf_{seed}_{cell}_{minutes:g}.csv"); ip.write_csv(p, r)
rec = sj.load_record(p)
p70 = p.with_name(p.stem + "_70.csv")
sj.atomic_write_csv(p70, {"time_s": rec.time[:h0], "voltage_V": rec.u[:h0], "displacement_mm": rec.y[:h0]})
t0 = time.time()
model, doc, _ = fit_record(sj.load_record(p70), model=cls, **({"thresholds": True, "tilts": True} if cls == "cascade" else {}))
e = np.asarray(sj.simulate(model, rec.u, rec.dt)) - rec.y
row = dict(seed=seed, cell=cell, minutes=minutes, mode=mode, cls=cls, kept=doc["settings"].get("structure_choice", {}).get("kept") if isinstance(doc["settings"].get("structure_choice"), dict) else None,
           split_train=doc["metrics"]["train"]["rmse"] / sd, split_val=doc["metrics"]["validation"]["rmse"] / sd,
           train=float(np.sqrt(np.mean(e[:h0] ** 2)) / sd), held=float(np.sqrt(np.mean(e[h0:] ** 2)) / sd), seconds=round(time.time() - t0, 1))
print(json.dumps(row), flush=True)
for nline in doc.get("notes", []): print("NOTE", str(nline)[:300])
with open("/tmp/s29/patched_fit.jsonl", "a") as f:
    f.write(json.dumps(row) + "\n")
if len(sys.argv) > 6 and sys.argv[6] == "post":
    from smafl_jax.identify import default_trainable
    d70 = [(np.asarray(rec.u[:h0]), np.asarray(rec.y[:h0]), rec.dt)]
    w70 = [np.ones(h0)]
    for it in range(2):
        if getattr(model.hysteresis, "init", None) != "fitted":
            model = model.with_hysteresis(model.hysteresis.with_fitted_memory())
        m1, l1 = search(model, d70, w70)
        res = sj.fit(m1, d70, weights=w70, init=None, trainable=default_trainable(m1, thresholds=True, tilts=True))
        model = res.model
        e = np.asarray(sj.simulate(model, rec.u, rec.dt)) - rec.y
        print(json.dumps(dict(post=it, k1=float(model.thermal.k1), u0=None if model.thermal.u0 is None else float(model.thermal.u0), init=model.thermal.init, sees=model.sees, train=float(np.sqrt(np.mean(e[:h0] ** 2)) / sd), held=float(np.sqrt(np.mean(e[h0:] ** 2)) / sd))), flush=True)
    xh = np.asarray(r["sim"]["x_h"]); xm = np.asarray(model.hysteresis_input(jnp.asarray(rec.u), rec.dt))
    print("x err rms", float(np.sqrt(np.mean((xm - xh) ** 2))), "x range", float(np.ptp(xh)))
    T = len(e); blk = int(60 / rec.dt)
    for k0 in range(0, T, blk):
        sl = slice(k0, min(k0 + blk, T))
        print(f"{k0 * rec.dt:6.0f}s {'H' if k0 >= h0 else 'T'} err/sd {np.sqrt(np.mean(e[sl] ** 2)) / sd:6.2f}  x {xh[sl].min():.2f}-{xh[sl].max():.2f}")
