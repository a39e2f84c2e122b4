"""``smafl sample DATA.csv --fit fit.json --out DIR``: Bayesian uncertainty of a fitted model (emcee).

Writes to DIR: ``chain.h5`` (emcee HDF5 backend; rerunning the same command
resumes an interrupted run), ``summary.json``, ``parameters.csv``,
``corner.png``, ``trace.png``, ``predictive_time.png``, ``predictive_loop.png``,
``predictive.csv`` and ``run.json`` (the settings the chain belongs to).
"""

from __future__ import annotations

import hashlib
import json
import sys
import warnings
from pathlib import Path

import numpy as np

from .._errors import UserInputError


def add_parser(sub):
    p = sub.add_parser("sample", help="posterior uncertainty of a fitted model by MCMC (emcee), with diagnostics and plots")
    p.add_argument("data_csv", help="CSV record to condition on (time_s, input, output)")
    p.add_argument("--fit", required=True, help="fit.json (or model file) whose model is the starting point")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--steps", type=int, default=3000, help="chain length per walker (default 3000)")
    p.add_argument("--walkers", type=int, default=None, help="number of walkers (default max(32, 2 ndim + 2))")
    p.add_argument(
        "--burn", type=int, default=None, help="steps discarded as burn-in (default: automatic, from the autocorrelation time)"
    )
    p.add_argument(
        "--linear",
        choices=["auto", "sample", "marginalise", "profile"],
        default="auto",
        help="hysteresis weights (EUPI gains, Preisach relay weights): sample them, marginalise them analytically "
        "(Gaussian prior) or profile them; auto = marginalise when the output is linear in them, else sample",
    )
    p.add_argument("--noise", choices=["gaussian", "student-t"], default="gaussian", help="noise model (scale is sampled)")
    p.add_argument("--nu", type=float, default=4.0, help="Student-t degrees of freedom (default 4)")
    p.add_argument(
        "--priors", default=None, help='JSON file overriding priors: {"thermal.k1": {"dist": "lognormal", "loc": -3, "scale": 1}}'
    )
    p.add_argument("--gain-scale", type=float, default=None, help="prior sd of marginalised gains (default 10x output range)")
    p.add_argument(
        "--heldout", default=None, help="held-out CSV for the predictive check (default: the last --holdout-fraction of DATA)"
    )
    p.add_argument(
        "--holdout-fraction",
        type=float,
        default=0.25,
        help="tail of DATA held out when no --heldout is given (default 0.25; 0 = use all)",
    )
    p.add_argument("--input", default=None, help="input column (default: the fit's)")
    p.add_argument("--output", default=None, help="output column (default: the fit's)")
    p.add_argument("--draws", type=int, default=200, help="posterior draws for the predictive bands (default 200)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--restart", action="store_true", help="discard an existing chain in DIR instead of resuming it")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=run)
    return p


def _sha(path):
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def run(args):
    from .. import _bayes as B
    from .. import load_model_file, load_record
    from .._io import atomic_savefig, atomic_write_json, atomic_write_text, prepare_out_dir
    from .._plots_bayes import corner_figure, predictive_loop_figure, predictive_time_figure, trace_figure

    if args.steps < 10:
        raise UserInputError(f"--steps must be >= 10, got {args.steps}")
    if not 0.0 <= args.holdout_fraction < 0.9:
        raise UserInputError(f"--holdout-fraction must be in [0, 0.9), got {args.holdout_fraction}")
    if args.draws < 2:
        raise UserInputError(f"--draws must be >= 2, got {args.draws}")
    if args.burn is not None and not 0 <= args.burn < args.steps:
        raise UserInputError(f"--burn must be in [0, --steps) = [0, {args.steps}), got {args.burn}")
    if args.walkers is not None and args.walkers < 2:
        raise UserInputError(f"--walkers must be >= 2, got {args.walkers}")
    if args.gain_scale is not None and not (np.isfinite(args.gain_scale) and args.gain_scale > 0):
        raise UserInputError(f"--gain-scale must be > 0, got {args.gain_scale}")
    if not (np.isfinite(args.nu) and args.nu > 0):
        raise UserInputError(f"--nu must be > 0, got {args.nu}")
    model, doc = load_model_file(args.fit)
    B.check_model_supported(model, where=args.fit)
    info = doc.get("data", {}) if isinstance(doc.get("data"), dict) else {}
    rec = load_record(
        args.data_csv, input=args.input or info.get("input_column"), output=args.output or info.get("output_column")
    )
    if rec.y is None:
        raise UserInputError(f"{args.data_csv}: no output column to condition on")
    fit_dt = info.get("sample_time_s")
    if fit_dt and not np.isclose(fit_dt, rec.dt, rtol=0.02):
        print(f"note: the model was fitted at dt={fit_dt:g} s and {args.data_csv} has dt={rec.dt:g} s", file=sys.stderr)
    if args.heldout:
        held = load_record(args.heldout, input=rec.input_name, output=rec.output_name)
        n_train = len(rec)
    else:
        held = None
        n_train = len(rec) - int(round(args.holdout_fraction * len(rec)))
        if n_train < 10:
            raise UserInputError(f"{args.data_csv}: only {n_train} samples left for sampling after holding out the tail")
    linear = args.linear
    if linear == "auto":
        linear = "marginalise" if "marginalise" in B.linear_modes(model) else "sample"
        if linear == "marginalise" and args.noise != "gaussian":
            linear = "profile"
    priors = B.load_priors(args.priors) if args.priors else None
    post = B.Posterior(
        model,
        (rec.u[:n_train], rec.y[:n_train]),
        rec.dt,
        noise=args.noise,
        nu=args.nu,
        priors=priors,
        linear=linear,
        gain_scale=args.gain_scale,
    )
    n_walkers = B.resolve_walkers(post.ndim, args.walkers)  # checked before anything is written

    out = prepare_out_dir(args.out)
    chain_path = out / "chain.h5"
    settings = {
        "data_sha256": rec.sha256,
        "fit_sha256": _sha(args.fit),
        "n_train": n_train,
        "linear": linear,
        "noise": args.noise,
        "nu": args.nu,
        "priors": {k: v.to_dict() for k, v in post.priors.items()},
        "gain_scale": post.gain_scale,
        "walkers": args.walkers,
        "seed": args.seed,
        "names": post.names,
    }
    run_json = out / "run.json"
    resume = chain_path.exists() and not args.restart
    if resume:
        try:
            old = json.loads(run_json.read_text())
        except (OSError, json.JSONDecodeError):
            old = None
        if old != json.loads(json.dumps(settings)):
            raise UserInputError(
                f"{chain_path} belongs to a run with other data or settings (see {run_json}); "
                "pass --restart to discard it or choose another --out"
            )
    atomic_write_json(run_json, settings)
    print(
        f"sampling {post.ndim} parameters ({', '.join(post.names[:6])}{' ...' if post.ndim > 6 else ''}); "
        f"gains: {linear}; noise: {args.noise}",
        file=sys.stderr,
    )
    result = B.run_sampler(
        post, args.steps, n_walkers=n_walkers, path=chain_path, seed=args.seed, resume=resume, progress=not args.no_progress
    )

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", B.ChainTooShortWarning)  # reported below and in summary.json
        summary = B.summarize(post, result, args.burn)
    summary["data"] = {
        "file": Path(args.data_csv).name,
        "sha256": rec.sha256,
        "input_column": rec.input_name,
        "output_column": rec.output_name,
        "n_train": n_train,
        "sample_time_s": rec.dt,
        "heldout": Path(args.heldout).name
        if args.heldout
        else (f"last {len(rec) - n_train} samples" if n_train < len(rec) else None),
    }
    summary["fit"] = str(args.fit)

    # -- figures and tables ------------------------------------------------
    burn = summary["burn"]
    flat = result.chain[burn:].reshape(-1, post.ndim)
    rng = np.random.default_rng(args.seed + 1)
    idx = rng.choice(flat.shape[0], size=min(args.draws, flat.shape[0]), replace=False)
    phys_flat = post.physical(flat)
    from .._reportdoc import unit_of

    y_unit = unit_of(rec.output_name, getattr(rec, "units", None))
    atomic_savefig(corner_figure(phys_flat, post.names, output_unit=y_unit), out / "corner.png")
    chain_phys = post.physical(result.chain.reshape(-1, post.ndim)).reshape(result.chain.shape)
    atomic_savefig(trace_figure(chain_phys, post.names, burn, output_unit=y_unit), out / "trace.png")
    target = held if held is not None else rec
    f, yrep = post.predict(flat[idx], target.u, target.dt, rng)
    mask = np.zeros(len(target), bool) if held is not None else (np.arange(len(rec)) < n_train)
    ylabel = f"{target.output_name}"
    fig, cover = predictive_time_figure(target.time, target.y, f, yrep, mask, ylabel=ylabel)
    atomic_savefig(fig, out / "predictive_time.png")
    atomic_savefig(
        predictive_loop_figure(target.u, target.y, f, mask, xlabel=target.input_name, ylabel=ylabel), out / "predictive_loop.png"
    )
    fq = np.quantile(f, [0.025, 0.5, 0.975], axis=0)
    yq = np.quantile(yrep, [0.025, 0.975], axis=0)
    from .._io import atomic_write_csv

    atomic_write_csv(
        out / "predictive.csv",
        {
            "time_s": target.time,
            target.input_name: target.u,
            target.output_name: target.y,
            "heldout": (~mask).astype(float),
            "median": fq[1],
            "model_q025": fq[0],
            "model_q975": fq[2],
            "pred_q025": yq[0],
            "pred_q975": yq[1],
        },
    )
    summary["heldout_coverage_95"] = cover
    atomic_write_json(out / "summary.json", summary)
    lines = ["name,mean,sd,q025,q975,ess,autocorr_time"]
    for name, s in summary["parameters"].items():
        lines.append(
            f"{name},{s['mean']:.8g},{s['sd']:.8g},{s['q025']:.8g},{s['q975']:.8g},{s['ess']:.1f},{s['autocorr_time']:.2f}"
        )
    atomic_write_text(out / "parameters.csv", "\n".join(lines) + "\n")

    # -- console report ------------------------------------------------------
    print(f"{'parameter':<22}{'mean':>12}{'sd':>12}{'2.5 %':>12}{'97.5 %':>12}{'ESS':>8}")
    for name, s in list(summary["parameters"].items()):
        print(f"{name:<22}{s['mean']:>12.5g}{s['sd']:>12.4g}{s['q025']:>12.5g}{s['q975']:>12.5g}{s['ess']:>8.0f}")
    for name, s in summary["derived"].items():
        if "mean" in s:
            print(f"{name:<22}{s['mean']:>12.5g}{s['sd']:>12.4g}{s['q025']:>12.5g}{s['q975']:>12.5g}")
        else:
            print(f"{name}: not identified ({s['note']})")
    print(
        f"acceptance fraction {summary['acceptance_fraction']:.3f}; max autocorrelation time {summary['autocorr_time_max']:.1f} "
        f"steps; {summary['n_steps']} steps x {summary['n_walkers']} walkers, burn-in {burn}"
    )
    if cover is not None:
        print(f"held-out points inside the 95 % predictive band: {100 * cover:.1f} %")
    for w in summary["warnings"]:
        print(f"WARNING: {w}", file=sys.stderr)
    print(f"wrote {out}/summary.json, parameters.csv, corner.png, trace.png, predictive_time.png, predictive_loop.png")
    return 0
