"""Closed-loop sweep throughput: smafl_jax.sweep (vmap + scan) vs numpy loop, numba and python-control.

    python -m benchmarks.bench_control [--quick]

Workload: plant = datasets/truth.json (thermal + EUPI, 24 operators), composite
PID (PID + I-I compensator on the static EUPI, another 24 operators), sine
reference, dt = 0.01 s; a grid of 100 x 100 = 10,000 (Kp, Ki) configurations.
Unit: closed-loop steps per second (configurations x samples / wall time).
Ours: the whole sweep in one jitted vmap (compile excluded: warm-up call first).
numpy loop: the same loop per sample with numpy arrays for the operator bank,
timed on a subset of configurations and scaled linearly (stated in the note).
numba: the same loop as scalar code, `@njit`, all configurations.
python-control: the loop as a discrete-time `control.nlsys` whose update
function is the numpy step (python-control has no hysteresis block, but a
discrete nonlinear system with a Python update callback can express it), run with
`input_output_response`; timed on a subset and scaled.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from benchmarks._common import progress, row, time_call
else:
    from ._common import progress, row, time_call

ROOT = Path(__file__).resolve().parents[1]
RATIO_MEANING = "ours / baseline in closed-loop steps per second (> 1: ours faster)"


def _setup(quick):
    import jax.numpy as jnp

    import smafl_jax as sj
    from smafl_jax.control import PID, ClosedLoop, IICompensator, sine_reference

    truth = sj.load_model(ROOT / "datasets" / "truth.json")
    dt = 0.01
    duration = 2.0 if quick else 10.0
    ref = sine_reference(duration, dt)
    loop = ClosedLoop(plant=truth, pid=PID(35.0, 20.0, 0.0), reference=jnp.asarray(ref), compensator=IICompensator(truth, 10.0))
    kps, kis = np.linspace(5, 60, 100), np.linspace(0, 40, 100)
    return truth, dt, ref, loop, kps, kis


def _arrays(model):
    h = model.hysteresis
    n_alpha, n_ra = np.shape(h.w)
    r = np.concatenate([np.asarray(h.r_sym), np.tile(np.asarray(h.r_asym), n_alpha)])
    al = np.concatenate([np.ones(len(h.r_sym)), np.repeat(np.asarray(h.alpha), n_ra)])
    return dict(
        k1=float(model.thermal.k1),
        k2=float(model.thermal.k2),
        r=r,
        al=al,
        w=np.asarray(h.linear_weights()),
        u_ref=float(h.u_ref),
        u_span=float(h.u_span),
        n_poly=len(h.poly),
    )


# -- numpy step (shared by the numpy loop and the python-control update function) --


def _np_loop(P, kp, ki, ref, dt, K=10.0, umax=7.4):
    a = np.exp(-P["k1"] * dt)
    g = P["k2"] / P["k1"]
    r, al, w, n_poly = P["r"], P["al"], P["w"], P["n_poly"]

    def eupi(ops, ueff, fresh):
        s = (ueff - P["u_ref"]) / P["u_span"]
        if fresh:
            ops = al * (s + r)
        ops = np.maximum(s - r, np.minimum(al * (s + r), ops))
        row_ = np.concatenate(([s], ops, s ** np.arange(2, 2 + n_poly), [1.0]))
        return ops, float(row_ @ w)

    theta = 0.0
    ops, y = eupi(None, 0.0, True)
    hops, yhat = eupi(None, 0.0, True)
    u2 = integ = 0.0
    err = 0.0
    for rk in ref:
        e = rk - y
        err += abs(e)
        u2 = min(max(u2 + dt * K * (rk - yhat), 0.0), umax)
        hops, yhat = eupi(hops, u2, False)
        p = kp * e
        it = integ + ki * dt * e
        raw = p + it + u2
        if not ((raw > umax and e > 0) or (raw < 0 and e < 0)):
            integ = it
        u = min(max(p + integ + u2, 0.0), umax)
        theta = a * theta + (1 - a) * g * u * u
        ops, y = eupi(ops, np.sqrt(max(theta, 0.0) * P["k1"] / P["k2"]), False)
    return err / len(ref)


def _numba_sweep():
    import numba

    @numba.njit(cache=False)
    def eupi(ops, ueff, fresh, r, al, w, u_ref, u_span, n_poly):
        s = (ueff - u_ref) / u_span
        n = r.shape[0]
        y = w[0] * s
        for i in range(n):
            if fresh:
                ops[i] = al[i] * (s + r[i])
            ops[i] = max(s - r[i], min(al[i] * (s + r[i]), ops[i]))
            y += w[1 + i] * ops[i]
        for m in range(n_poly):
            y += w[1 + n + m] * s ** (m + 2)
        return y + w[1 + n + n_poly]

    @numba.njit(cache=False)
    def sweep(kps, kis, ref, dt, k1, k2, r, al, w, u_ref, u_span, n_poly, K, umax):
        out = np.empty(kps.shape[0])
        a = np.exp(-k1 * dt)
        g = k2 / k1
        ops = np.empty(r.shape[0])
        hops = np.empty(r.shape[0])
        for c in range(kps.shape[0]):
            kp, ki = kps[c], kis[c]
            theta = 0.0
            y = eupi(ops, 0.0, True, r, al, w, u_ref, u_span, n_poly)
            yhat = eupi(hops, 0.0, True, r, al, w, u_ref, u_span, n_poly)
            u2 = 0.0
            integ = 0.0
            err = 0.0
            for k in range(ref.shape[0]):
                rk = ref[k]
                e = rk - y
                err += abs(e)
                u2 = min(max(u2 + dt * K * (rk - yhat), 0.0), umax)
                yhat = eupi(hops, u2, False, r, al, w, u_ref, u_span, n_poly)
                p = kp * e
                it = integ + ki * dt * e
                raw = p + it + u2
                if not ((raw > umax and e > 0) or (raw < 0 and e < 0)):
                    integ = it
                u = min(max(p + integ + u2, 0.0), umax)
                theta = a * theta + (1 - a) * g * u * u
                y = eupi(ops, np.sqrt(max(theta, 0.0) * k1 / k2), False, r, al, w, u_ref, u_span, n_poly)
            out[c] = err / ref.shape[0]
        return out

    return sweep


def _control_sim(P, kp, ki, ref, dt, K=10.0, umax=7.4):
    """The same closed loop as a discrete-time python-control nlsys (state: theta, u2, integ, y, yhat, ops, hops)."""
    import control as ct

    a = np.exp(-P["k1"] * dt)
    g = P["k2"] / P["k1"]
    r, al, w, n_poly = P["r"], P["al"], P["w"], P["n_poly"]
    n = len(r)

    def eupi(ops, ueff):
        s = (ueff - P["u_ref"]) / P["u_span"]
        ops = np.maximum(s - r, np.minimum(al * (s + r), ops))
        return ops, float(np.concatenate(([s], ops, s ** np.arange(2, 2 + n_poly), [1.0])) @ w)

    def upd(t, x, u_in, params):
        rk = u_in[0]
        theta, u2, integ, y, yhat = x[:5]
        ops, hops = x[5 : 5 + n], x[5 + n :]
        e = rk - y
        u2 = min(max(u2 + dt * K * (rk - yhat), 0.0), umax)
        hops, yhat = eupi(hops, u2)
        p = kp * e
        it = integ + ki * dt * e
        raw = p + it + u2
        if not ((raw > umax and e > 0) or (raw < 0 and e < 0)):
            integ = it
        u = min(max(p + integ + u2, 0.0), umax)
        theta = a * theta + (1 - a) * g * u * u
        ops, y = eupi(ops, np.sqrt(max(theta, 0.0) * P["k1"] / P["k2"]))
        return np.concatenate(([theta, u2, integ, y, yhat], ops, hops))

    def outf(t, x, u_in, params):
        return np.array([u_in[0] - x[3]])

    sys_ = ct.nlsys(upd, outf, inputs=1, outputs=1, states=5 + 2 * n, dt=dt)
    ops0 = al * r  # descended at s = 0
    y0 = float(np.concatenate(([0.0], ops0, np.zeros(n_poly), [1.0])) @ w)
    x0 = np.concatenate(([0.0, 0.0, 0.0, y0, y0], ops0, ops0))
    T = np.arange(len(ref)) * dt
    resp = ct.input_output_response(sys_, T, ref[None, :], x0)
    return float(np.mean(np.abs(resp.outputs)))


def run(quick: bool = False) -> list[dict]:
    import jax

    from smafl_jax.control import sweep

    truth, dt, ref, loop, kps, kis = _setup(quick)
    n_steps = len(ref)
    grid = {"pid.kp": kps, "pid.ki": kis}
    n_cfg = kps.size * kis.size
    KP, KI = (x.ravel() for x in np.meshgrid(kps, kis, indexing="ij"))
    work = n_cfg * n_steps
    rows = []
    unit = "closed-loop steps/s"
    progress(f"control: JAX sweep of {n_cfg} configs x {n_steps} steps on {len(jax.devices())} device(s)")
    res = {}

    def ours():
        res["m"] = sweep(loop, dt, grid).metrics["e_mean_mm"]
        return res["m"]

    t_ours = time_call(ours, repeat=2 if quick else 3)["best_s"]
    ours_rate = work / t_ours
    e_ours = res["m"].ravel()

    P = _arrays(truth)
    n_sub = 4 if quick else 10
    sub = np.linspace(0, n_cfg - 1, n_sub).astype(int)
    progress(f"control: numpy loop on {n_sub} configs")
    t0 = time.perf_counter()
    e_np = np.array([_np_loop(P, KP[i], KI[i], ref, dt) for i in sub])
    t_np = (time.perf_counter() - t0) / n_sub * n_cfg
    agree_np = float(np.max(np.abs(e_np - e_ours[sub])))
    rows.append(
        row(
            f"sweep {n_cfg} configs x {n_steps} steps: vmap+scan vs numpy loop",
            ours_rate,
            work / t_np,
            unit,
            note=f"numpy timed on {n_sub} configs, scaled x{n_cfg // n_sub}; max |e_mean diff| {agree_np:.1e} mm",
            ours_s=t_ours,
            baseline_s=t_np,
            baseline_extrapolated=True,
            n_configs=n_cfg,
            n_steps=n_steps,
        )
    )

    progress("control: numba (all configs)")
    nb = _numba_sweep()
    args = (ref, dt, P["k1"], P["k2"], P["r"], P["al"], P["w"], P["u_ref"], P["u_span"], P["n_poly"], 10.0, 7.4)
    nb(KP[:2], KI[:2], *args)  # compile
    out = {}

    def numba_all():
        out["e"] = nb(KP, KI, *args)
        return out["e"]

    t_nb = time_call(numba_all, repeat=2 if quick else 3)["best_s"]
    agree_nb = float(np.max(np.abs(out["e"] - e_ours)))
    rows.append(
        row(
            f"sweep {n_cfg} configs x {n_steps} steps: vmap+scan vs numba",
            ours_rate,
            work / t_nb,
            unit,
            note=f"numba single-threaded, all configs; max |e_mean diff| {agree_nb:.1e} mm",
            ours_s=t_ours,
            baseline_s=t_nb,
            n_configs=n_cfg,
            n_steps=n_steps,
        )
    )

    try:
        import control  # noqa: F401
    except ImportError:
        rows.append(row("python-control nlsys", ours_rate, None, unit, note="python-control not installed (pip install control)"))
        return rows
    n_ct = 2 if quick else 4
    sub_ct = sub[:n_ct]
    progress(f"control: python-control nlsys on {n_ct} configs")
    t0 = time.perf_counter()
    e_ct = np.array([_control_sim(P, KP[i], KI[i], ref, dt) for i in sub_ct])
    t_ct = (time.perf_counter() - t0) / n_ct * n_cfg
    agree_ct = float(np.max(np.abs(e_ct - e_ours[sub_ct])))
    rows.append(
        row(
            f"sweep {n_cfg} configs x {n_steps} steps: vmap+scan vs python-control nlsys",
            ours_rate,
            work / t_ct,
            unit,
            note=f"discrete nlsys with a Python update callback (no hysteresis block in python-control); timed on {n_ct} configs, "
            f"scaled x{n_cfg // n_ct}; max |e_mean diff| {agree_ct:.1e} mm",
            ours_s=t_ours,
            baseline_s=t_ct,
            baseline_extrapolated=True,
            n_configs=n_cfg,
            n_steps=n_steps,
        )
    )
    return rows


if __name__ == "__main__":
    quick = "--quick" in sys.argv
    for r in run(quick):
        print(
            f"{r['name']}: ours {r['ours']:.3g} vs {r['baseline'] if r['baseline'] is None else format(r['baseline'], '.3g')} "
            f"{r['unit']} -> ratio {r['ratio'] if r['ratio'] is None else format(r['ratio'], '.3g')}  ({r.get('note', '')})"
        )
