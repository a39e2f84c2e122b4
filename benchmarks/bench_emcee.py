"""emcee log-probability evaluations per second: vectorised jitted JAX vs a per-walker numpy loop.

Problem: the full cascade of ``datasets/truth.json`` (k1, the 28 EUPI gains and
the noise scale: 30 parameters, all sampled, ``linear="sample"``) on
``datasets/main_loop.csv`` (1761 samples, 24 play operators), Gaussian noise,
the default priors, 64 walkers.

* ours: `smafl_jax.Posterior` (one ``jax.jit(jax.vmap(log_prob))`` over the
  walkers) passed to ``emcee.EnsembleSampler(..., vectorize=True)``;
* baseline: the same log-posterior written as a plain numpy loop of the cascade
  (thermal recurrence, then the play-operator bank stepped in a Python loop,
  numpy-vectorised over the operators), called by emcee once per walker.

Both give the same log-probability (checked to 1e-9 relative before timing).
Rate = walker evaluations / wall time of ``run_mcmc`` (compilation excluded by
a warm-up), measured in the same process; emcee's own overhead is included on
both sides.  The second row times the log-probability alone on a batch of
64 walkers (no emcee).
"""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import numpy as np

if __package__ in (None, ""):  # allow `python benchmarks/bench_emcee.py`
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from benchmarks._common import progress, row
else:
    from ._common import progress, row

RATIO_MEANING = "ours / baseline in log-probability evaluations per second (> 1: ours faster)"
ROOT = Path(__file__).resolve().parents[1]
N_WALKERS = 64


def _softplus(x):
    return np.logaddexp(0.0, x)


def _log_sigmoid(x):
    return -np.logaddexp(0.0, -x)


def _prior_np(prior, x):
    x = np.asarray(x, float)
    if prior.dist == "normal":
        z = (x - prior.loc) / prior.scale
        return float(np.sum(-0.5 * z * z - math.log(prior.scale) - 0.5 * math.log(2 * math.pi)))
    if prior.dist == "lognormal":
        lx = np.log(x)
        z = (lx - prior.loc) / prior.scale
        return float(np.sum(-0.5 * z * z - math.log(prior.scale) - 0.5 * math.log(2 * math.pi) - lx))
    if prior.dist == "halfnormal":
        z = x / prior.scale
        return float(np.sum(-0.5 * z * z - math.log(prior.scale) + 0.5 * math.log(2 / math.pi)))
    raise NotImplementedError(prior.dist)


class NumpyLogProb:
    """Per-walker numpy implementation of the same log-posterior (loop over time)."""

    POSITIVE: frozenset = frozenset({"thermal.k1", "hysteresis.gain", "hysteresis.v", "hysteresis.w", "noise.sigma"})

    def __init__(self, post, model, u, y, dt):
        self.post, self.u, self.y, self.dt = post, np.asarray(u, float), np.asarray(y, float), float(dt)
        h = model.hysteresis
        r, a = h._bank()
        self.r, self.a = np.asarray(r, float), np.asarray(a, float)
        self.u_ref, self.u_span = float(h.u_ref), float(h.u_span)
        self.k2 = float(model.thermal.k2)
        self.n_poly = int(np.shape(h.poly)[0])
        self.layout = []
        i = 0
        for name, shape in zip(post.names_leaf, post.shapes_leaf):
            size = int(np.prod(shape, dtype=int))
            self.layout.append((name, i, size, shape))
            i += size

    def __call__(self, theta):
        vals, lp = {}, 0.0
        for name, i, size, _shape in self.layout:
            raw = theta[i : i + size]
            if name in self.POSITIVE:
                vals[name] = _softplus(raw)
                lp += float(np.sum(_log_sigmoid(raw)))
            else:
                vals[name] = raw.copy()
            lp += _prior_np(self.post.priors[name], vals[name])
        k1 = float(vals["thermal.k1"][0])
        sigma = float(vals["noise.sigma"][0])
        # thermal recurrence (exact ZOH), steady initial state
        aa, g = math.exp(-k1 * self.dt), self.k2 / k1
        theta_t = g * self.u[0] ** 2
        u_eff = np.empty_like(self.u)
        for k, uk in enumerate(self.u):
            theta_t = aa * theta_t + (1.0 - aa) * g * uk * uk
            u_eff[k] = math.sqrt(theta_t * k1 / self.k2) if theta_t > 0 else 0.0
        s = (u_eff - self.u_ref) / self.u_span
        # play-operator bank, "descended" initial state
        r, a = self.r, self.a
        state = a * (s[0] + r)
        ops = np.empty((len(s), len(r)))
        for k, sk in enumerate(s):
            state = np.maximum(sk - r, np.minimum(a * (sk + r), state))
            ops[k] = state
        w = np.concatenate([vals["hysteresis.gain"], vals["hysteresis.v"], vals["hysteresis.w"].ravel()])
        out = s * w[0] + ops @ w[1:]
        for m, c in enumerate(vals["hysteresis.poly"]):
            out = out + c * s ** (m + 2)
        out = out + vals["hysteresis.offset"][0]
        res = out - self.y
        n = len(res)
        lp += -0.5 * float(np.sum((res / sigma) ** 2)) - n * math.log(sigma) - 0.5 * n * math.log(2 * math.pi)
        return lp if math.isfinite(lp) else -math.inf


def _setup():
    import smafl_jax as sj

    rec = sj.load_record(ROOT / "datasets" / "main_loop.csv")
    truth = sj.load_model(ROOT / "datasets" / "truth.json")
    post = sj.Posterior(truth, rec, linear="sample")
    return sj, rec, truth, post


def run(quick: bool = False) -> list[dict]:
    import emcee

    sj, rec, truth, post = _setup()
    ref = NumpyLogProb(post, truth, rec.u, rec.y, rec.dt)
    rng = np.random.default_rng(0)
    p0 = post.initial_ball(N_WALKERS, rng)
    ours_lp = post(p0)
    base_lp = np.array([ref(t) for t in p0[:4]])
    if not np.allclose(ours_lp[:4], base_lp, rtol=1e-9, atol=1e-6):
        raise RuntimeError(f"implementations disagree: {ours_lp[:4]} vs {base_lp}")
    post(p0[: N_WALKERS // 2])  # compile the half-ensemble shape emcee uses

    steps_ours = 60 if quick else 300
    steps_base = 2 if quick else 6
    progress(
        f"emcee: {post.ndim} parameters, {N_WALKERS} walkers, {len(rec)} samples; ours {steps_ours} steps, numpy {steps_base} steps"
    )

    s_ours = emcee.EnsembleSampler(N_WALKERS, post.ndim, post, vectorize=True)
    t0 = time.perf_counter()
    s_ours.run_mcmc(p0, steps_ours)
    t_ours = time.perf_counter() - t0
    s_base = emcee.EnsembleSampler(N_WALKERS, post.ndim, ref)
    t0 = time.perf_counter()
    s_base.run_mcmc(p0, steps_base)
    t_base = time.perf_counter() - t0
    # emcee evaluates the initial ensemble once plus one proposal per walker per step
    rate_ours = N_WALKERS * (steps_ours + 1) / t_ours
    rate_base = N_WALKERS * (steps_base + 1) / t_base

    # the log-probability alone, one batch of walkers
    reps = 20 if quick else 100
    post(p0)
    t0 = time.perf_counter()
    for _ in range(reps):
        post(p0)
    t_batch = (time.perf_counter() - t0) / reps
    n_loop = 8 if quick else N_WALKERS
    t0 = time.perf_counter()
    for t in p0[:n_loop]:
        ref(t)
    t_loop = (time.perf_counter() - t0) / n_loop
    size = {"n_params": post.ndim, "n_walkers": N_WALKERS, "n_samples": len(rec), "n_operators": truth.hysteresis.n_operators}
    return [
        row(
            "emcee run, full cascade (30 params, 64 walkers, 1761 samples)",
            rate_ours,
            rate_base,
            "evals/s",
            note=f"vectorize=True + jit(vmap) vs per-walker numpy loop; {steps_ours} vs {steps_base} steps",
            seconds_ours=t_ours,
            seconds_baseline=t_base,
            **size,
        ),
        row(
            "log-prob only, batch of 64 walkers",
            N_WALKERS / t_batch,
            1.0 / t_loop,
            "evals/s",
            note="one jit(vmap) call vs a Python loop of numpy evaluations",
            **size,
        ),
    ]


if __name__ == "__main__":
    import argparse

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    a = ap.parse_args()
    for r in run(a.quick):
        print(f"{r['name']}: ours {r['ours']:.4g} {r['unit']}, baseline {r['baseline']:.4g} {r['unit']}, ratio {r['ratio']:.1f}x")
