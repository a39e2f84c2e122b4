"""``smafl sample DATA.csv [more records] --fit fit.json --out DIR``: Bayesian uncertainty of a fitted model (emcee).

Writes to DIR: ``chain.h5`` (emcee HDF5 backend; rerunning the same command
resumes an interrupted run), ``summary.json``, ``parameters.csv``,
``corner.png``, ``trace.png``, ``predictive_time.png``, ``predictive_loop.png``,
``predictive.csv`` and ``run.json`` (the settings the chain belongs to).
The workflow is `smafl_jax.workflows.sample_posterior`; this module parses the
arguments and prints its results.
"""

from __future__ import annotations

import sys

from ._lines import workflow_lines_on_stderr
from .check import TIME_HELP, add_resample_argument, add_window_argument


def add_parser(sub):
    p = sub.add_parser("sample", help="posterior uncertainty of a fitted model by MCMC (emcee), with diagnostics and plots")
    p.add_argument(
        "data_csv",
        nargs="+",
        help="CSV record to condition on (time_s, input, output); several files, a folder (its *.csv) or a glob condition "
        "ONE model on all of them, each record run from its own start (a joint fit's training record: its fitted start)",
    )
    p.add_argument("--fit", required=True, help="fit.json (or model file) whose model is the starting point")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--steps", type=int, default=3000, help="chain length per walker, at least 10 (default 3000)")
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
        "--heldout",
        default=None,
        help="held-out CSV for the predictive check, run as a new record (default: the last --holdout-fraction of each record)",
    )
    p.add_argument(
        "--holdout-fraction",
        type=float,
        default=0.25,
        help="tail of each record held out when no --heldout is given (default 0.25; 0 = use all)",
    )
    p.add_argument("--input", default=None, help="input column (default: the fit's)")
    p.add_argument("--output", default=None, help="output column (default: the fit's)")
    p.add_argument("--time", default=None, metavar="COL", help=TIME_HELP)
    add_resample_argument(p)
    add_window_argument(p)
    p.add_argument("--draws", type=int, default=200, help="posterior draws for the predictive bands (default 200)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--restart", action="store_true", help="discard an existing chain in DIR instead of resuming it")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=run)
    return p


#: How the library's error messages name its settings: as this command's flags.
OPTION_NAMES = {
    "steps": "--steps",
    "walkers": "--walkers",
    "burn": "--burn",
    "draws": "--draws",
    "holdout_fraction": "--holdout-fraction",
    "gain_scale": "--gain-scale",
    "nu": "--nu",
    "linear": "--linear",
    "restart": "--restart",
    "out": "--out",
}


def _interrupt_note(out, steps, saved):
    """What an interrupt says (`set_interrupt_note`): the steps saved in the chain and the command that resumes it.

    ``saved["k"]`` is kept up to date by the sampler (in memory, so the watchdog thread can read it)."""
    import os

    from . import command_line

    def note():
        k = saved.get("k")
        if not k:
            return None  # nothing sampled yet: a rerun starts afresh
        chain = os.path.join(out, "chain.h5")
        again = command_line(drop=("--restart",))
        if k >= steps:
            return f"the chain is complete ({k} of {steps} steps saved in {chain}); `{again}` writes the results without sampling again"
        return f"{k} of {steps} steps are saved in {chain}; resume with: {again}"

    return note


def run(args):
    from ..data._data import parse_resample, parse_window
    from ..workflows import sample as W
    from . import set_interrupt_note

    saved = {}
    set_interrupt_note(_interrupt_note(args.out, args.steps, saved))
    with workflow_lines_on_stderr(W.__name__, warning_prefix=False):
        res = W.sample_posterior(
            args.data_csv[0] if len(args.data_csv) == 1 else args.data_csv,
            args.fit,
            out=args.out,
            heldout=args.heldout,
            steps=args.steps,
            walkers=args.walkers,
            burn=args.burn,
            linear=args.linear,
            noise=args.noise,
            nu=args.nu,
            priors=args.priors,
            gain_scale=args.gain_scale,
            holdout_fraction=args.holdout_fraction,
            input=args.input,
            output=args.output,
            time=args.time,
            resample=parse_resample(args.resample),
            window=parse_window(args.window),
            draws=args.draws,
            seed=args.seed,
            restart=args.restart,
            progress=not args.no_progress,
            option_names=OPTION_NAMES,
            on_step=lambda k: saved.update(k=k),
        )
    summary, out = res.summary, res.out
    print(f"{'parameter':<22}{'mean':>12}{'sd':>12}{'2.5 %':>12}{'97.5 %':>12}{'ESS':>8}")
    for name, s in summary["parameters"].items():
        print(f"{name:<22}{s['mean']:>12.5g}{s['sd']:>12.4g}{s['q025']:>12.5g}{s['q975']:>12.5g}{s['ess']:>8.0f}")
    if any(".memory[" in name for name in summary["parameters"]):  # a trial user could not read these rows
        print(
            "  (hysteresis.memory[i]: operator i's state at t = 0 as a logit of where it starts between its lower and "
            "upper bound, sigmoid(value); 0 = midway, -4 / +4 = 2 % from the lower / upper bound; a wide interval: the "
            "record does not pin that operator's start)"
        )
    for name, s in summary["derived"].items():
        if "mean" in s:
            print(f"{name:<22}{s['mean']:>12.5g}{s['sd']:>12.4g}{s['q025']:>12.5g}{s['q975']:>12.5g}")
        else:
            print(f"{name}: not identified ({s['note']})")
    print(
        f"acceptance fraction {summary['acceptance_fraction']:.3f}; max autocorrelation time {summary['autocorr_time_max']:.1f} "
        f"steps; {summary['n_steps']} steps x {summary['n_walkers']} walkers, burn-in {summary['burn']}"
    )
    cover = summary["heldout_coverage_95"]
    if cover is not None:
        print(f"held-out points inside the 95 % predictive band: {100 * cover:.1f} %")
    for name, c in (summary.get("heldout_coverage_95_per_record") or {}).items():
        print(f"  {name}: {'-' if c is None else f'{100 * c:.1f} %'}")
    for w in summary["warnings"]:
        print(f"WARNING: {w}", file=sys.stderr)
    print(f"wrote {out}/summary.json, parameters.csv, corner.png, trace.png, predictive_time.png, predictive_loop.png")
    return 0
