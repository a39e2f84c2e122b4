"""Calibration of the posterior intervals on synthetic data with known truth.

Two seeded studies, each over ``n_rep`` replicates (new noise and, for the
cascade, a new random drive per replicate):

- ``joule``: the JouleThermal model alone (k1, k2 and the noise scale sampled)
  on a 100 s voltage-step record, Gaussian noise 0.05; start: `smafl_jax.fit`.
- ``cascade``: a small cascade (k1 sampled, EUPI gains marginalised) on a
  random-reversal drive, noise 0.01 mm; start: best point of a k1 grid of the
  same posterior (the gains' fit is implied by the marginalisation).

For each replicate the nominal 90 % (and 95 %) equal-tailed intervals of the
thermal parameters are checked against the truth; the coverage over the
replicates should be near nominal (target: 80-98 % for 90 %).

    python experiments/calibration.py --study both --reps 60 --cascade-reps 30 --out experiments/out
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import jax.numpy as jnp
import numpy as np

import smafl_jax as sj

K1, K2 = 0.0625, 0.055


def joule_record(rng, n=200, dt=0.5, sigma=0.05):
    u = np.zeros(n)
    u[20:] = 5.0
    u[n // 2 :] = 2.0
    u[3 * n // 4 :] = 7.0
    truth = sj.JouleThermal(k1=jnp.asarray(K1), k2=jnp.asarray(K2))
    return u, np.asarray(truth.simulate(u, dt)) + sigma * rng.standard_normal(n), dt


def _interval_hits(summary, names, truth):
    out = {}
    for name in names:
        p = summary["parameters"][name]
        out[name] = {
            "q05": p["q05"],
            "q95": p["q95"],
            "q025": p["q025"],
            "q975": p["q975"],
            "mean": p["mean"],
            "hit90": bool(p["q05"] <= truth[name] <= p["q95"]),
            "hit95": bool(p["q025"] <= truth[name] <= p["q975"]),
        }
    return out


def _coverage(reps, names):
    return (
        {n: float(np.mean([r[n]["hit90"] for r in reps])) for n in names},
        {n: float(np.mean([r[n]["hit95"] for r in reps])) for n in names},
    )


def run_joule(n_rep=100, n_steps=1500, seed=0, progress=True, n_walkers=16):
    """Coverage of k1 and k2 for the JouleThermal model alone."""
    names, truth = ["k1", "k2"], {"k1": K1, "k2": K2}
    reps, short = [], 0
    for r in range(n_rep):
        rng = np.random.default_rng([seed, r])
        u, y, dt = joule_record(rng)
        fit = sj.fit(sj.JouleThermal(), (u, y), dt)
        post = sj.Posterior(fit.model, (u, y), dt)
        run = sj.run_sampler(post, n_steps, n_walkers=n_walkers, seed=int(rng.integers(2**31)), progress=False)
        s = sj.summarize(post, run, warn=False)
        short += not s["reliable"]
        reps.append(_interval_hits(s, names, truth))
        if progress:
            print(f"joule {r + 1}/{n_rep}", file=sys.stderr, end="\r")
    c90, c95 = _coverage(reps, names)
    return {
        "study": "joule",
        "n_rep": n_rep,
        "n_steps": n_steps,
        "n_walkers": n_walkers,
        "truth": truth,
        "coverage90": c90,
        "coverage95": c95,
        "n_short_chains": short,
        "replicates": reps,
    }


def cascade_truth():
    m = sj.Cascade.from_range(7.4, n_sym=4, n_alpha=2, n_asym=2, poly_order=2)
    gains = np.array([0.3, 1.2, 0.6, 0.3, 0.15, 0.3, 0.1, 0.2, 0.05, 0.1, 0.25])
    return sj.Cascade(
        thermal=sj.JouleThermal(k1=jnp.asarray(K1), k2=jnp.asarray(K2)), hysteresis=m.hysteresis.with_linear_weights(gains)
    )


def cascade_record(rng, n=400, dt=0.5, sigma=0.01):
    knots = np.concatenate([[0.0], rng.uniform(0.0, 7.4, 9), [0.0]])
    u = np.interp(np.linspace(0, 1, n), np.linspace(0, 1, len(knots)), knots)
    return u, np.asarray(cascade_truth().simulate(u, dt)) + sigma * rng.standard_normal(n), dt


def run_cascade(n_rep=30, n_steps=600, seed=0, progress=True, n_walkers=12):
    """Coverage of the cascade's k1 with the EUPI gains marginalised."""
    names, truth = ["thermal.k1"], {"thermal.k1": K1}
    reps, short = [], 0
    template = cascade_truth()
    for r in range(n_rep):
        rng = np.random.default_rng([seed, 1000 + r])
        u, y, dt = cascade_record(rng)
        # start from the paper's k1; the Posterior's gains come from the marginalisation
        start = sj.Cascade(thermal=sj.JouleThermal(), hysteresis=template.hysteresis)
        post = sj.Posterior(start, (u, y), dt, linear="marginalise", sigma=0.02)
        # "fit": best point of the same posterior on a (k1, sigma) grid
        k1g, sg = np.meshgrid(np.geomspace(0.01, 0.5, 60), np.geomspace(0.003, 0.1, 12))
        grid = np.log(np.expm1(np.column_stack([k1g.ravel(), sg.ravel()])))
        best = grid[np.argmax(post(grid))]
        post.theta0 = best
        run = sj.run_sampler(post, n_steps, n_walkers=n_walkers, seed=int(rng.integers(2**31)), progress=False)
        s = sj.summarize(post, run, warn=False)
        short += not s["reliable"]
        reps.append(_interval_hits(s, names, truth))
        if progress:
            print(f"cascade {r + 1}/{n_rep}", file=sys.stderr, end="\r")
    c90, c95 = _coverage(reps, names)
    return {
        "study": "cascade",
        "n_rep": n_rep,
        "n_steps": n_steps,
        "n_walkers": n_walkers,
        "truth": truth,
        "coverage90": c90,
        "coverage95": c95,
        "n_short_chains": short,
        "replicates": reps,
    }


def figure(results, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = [(res, name) for res in results for name in res["truth"]]
    fig, axes = plt.subplots(len(panels), 1, figsize=(9, 2.4 * len(panels)), squeeze=False)
    for ax, (res, name) in zip(axes[:, 0], panels):
        reps = res["replicates"]
        x = np.arange(len(reps))
        lo = np.array([r[name]["q05"] for r in reps])
        hi = np.array([r[name]["q95"] for r in reps])
        mid = np.array([r[name]["mean"] for r in reps])
        hit = np.array([r[name]["hit90"] for r in reps])
        for ok, col in ((True, "C0"), (False, "C3")):
            m = hit == ok
            ax.errorbar(
                x[m],
                mid[m],
                yerr=[mid[m] - lo[m], hi[m] - mid[m]],
                fmt=".",
                ms=3,
                lw=0.8,
                color=col,
                label="covers truth" if ok else "misses truth",
            )
        ax.axhline(res["truth"][name], color="k", lw=0.8, label="truth")
        ax.set_ylabel(name)
        ax.set_title(
            f"{res['study']}: 90 % intervals of {name}, coverage {100 * res['coverage90'][name]:.0f} % "
            f"of {res['n_rep']} replicates (95 % intervals: {100 * res['coverage95'][name]:.0f} %)",
            fontsize=9,
        )
        ax.legend(fontsize=7, loc="upper right")
    axes[-1, 0].set_xlabel("replicate")
    fig.tight_layout()
    sj.atomic_savefig(fig, path)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--study", choices=["joule", "cascade", "both"], default="both")
    ap.add_argument("--reps", type=int, default=60, help="replicates of the joule study (default 60)")
    ap.add_argument("--cascade-reps", type=int, default=30, help="replicates of the cascade study (default 30)")
    ap.add_argument("--steps", type=int, default=1500, help="chain length of the joule study (cascade: 600)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default=str(Path(__file__).parent / "out"))
    args = ap.parse_args(argv)
    out = sj.prepare_out_dir(args.out, announce=False)
    results = []
    t0 = time.time()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sj.ChainTooShortWarning)
        if args.study in ("joule", "both"):
            results.append(run_joule(args.reps, n_steps=args.steps, seed=args.seed))
        if args.study in ("cascade", "both"):
            results.append(run_cascade(args.cascade_reps, seed=args.seed))
    elapsed = time.time() - t0
    for res in results:
        print(
            f"{res['study']}: {res['n_rep']} replicates, {res['n_steps']} steps x {res['n_walkers']} walkers; "
            f"90 % coverage {res['coverage90']}; 95 % coverage {res['coverage95']}; chains flagged short: {res['n_short_chains']}"
        )
    print(f"elapsed {elapsed:.0f} s")
    sj.atomic_write_json(out / "calibration.json", {"elapsed_s": elapsed, "command": " ".join(sys.argv), "results": results})
    figure(results, out / "calibration.png")
    print(f"wrote {out / 'calibration.json'} and {out / 'calibration.png'}")


if __name__ == "__main__":
    main()
