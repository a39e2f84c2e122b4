"""`smafl paper`: the paper's whole story on the bundled records, in one run and one report.

Sections (each produces numbers, figures and a short verdict for the report):
1. EUPI identification in the voltage domain (paper figs. 9-10, e_r vs 6.3 %);
2. Joule heat model alone, U^2 -> displacement (figs. 11-12, K1/K2 and the 0.510 mm max error);
3. joint cascade fit (thermal + EUPI) with held-out validation and recovery of the known truth;
4. posterior of the cascade (emcee) with derived quantities;
5. PID vs composite PID in closed loop (figs. 14-15, e_mean table);
6. residual diagnosis: on the bundled record, and on real measured SMA data when present.
Every number in the report is computed by this run; nothing is copied from a file
except the paper's own values, which are labelled as such.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path

import numpy as np

from .. import _config  # noqa: F401

__all__ = ["run_paper", "PAPER_VALUES"]

#: Numbers quoted by Xiang et al. (2017), shown next to ours (never used in computations).
PAPER_VALUES = {
    "eupi_e_r_percent": 6.3,
    "k1": 0.04988,
    "k2": 0.04172,
    "joule_max_error_mm": 0.510,
    "e_mean_sim": {
        ("composite", "sine"): 0.0027,
        ("composite", "step"): 0.0004,
        ("pid", "sine"): 0.0030,
        ("pid", "step"): 0.0009,
    },
    "e_mean_exp": {
        ("composite", "sine"): 0.0517,
        ("composite", "step"): 0.0326,
        ("pid", "sine"): 0.0934,
        ("pid", "step"): 0.1029,
    },
}


class _Progress:
    """Numbered section lines with the elapsed time, on the progress logger (the CLI shows them on stderr).

    The sections differ too much in cost for a mean-per-section estimate; the long ones report their own
    steps with an estimate (the sampler's bar, the diagnosis' records, candidates and null records).
    """

    def __init__(self, total):
        self.total, self.k, self.t0 = total, 0, time.perf_counter()

    def __call__(self, what):
        from .._progress import LOGGER, format_seconds

        self.k += 1
        LOGGER.info(f"[{self.k}/{self.total} {format_seconds(time.perf_counter() - self.t0)} elapsed] {what}")


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(fig, path):
    from .._io import atomic_savefig

    atomic_savefig(fig, path)
    _plt().close(fig)
    return path


def default_datasets_dir():
    """The repository's bundled `datasets/` folder."""
    return Path(__file__).resolve().parents[2] / "datasets"


def default_real_dir():
    """Where real measured data is read in place (beside the repository)."""
    return Path(__file__).resolve().parents[3] / "shared" / "data" / "real"


def _loop_figure(path, panels, title, xlabel="voltage (V)", ylabel="displacement (mm)"):
    """Input-output loops: panels = [(label, u, y_meas, y_model)]."""
    plt = _plt()
    fig, axes = plt.subplots(1, len(panels), figsize=(5 * len(panels), 4), squeeze=False)
    for ax, (label, u, y, yhat) in zip(axes[0], panels):
        ax.plot(u, y, ".", ms=2, color="0.5", label="measured")
        ax.plot(u, yhat, "-", lw=1.2, color="C3", label="model")
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel)
        ax.set_title(label)
        ax.legend(loc="upper left")
    fig.suptitle(title)
    return _save(fig, path)


def _time_figure(path, panels, title):
    """Time series with error: panels = [(label, t, y_meas, y_model)]."""
    plt = _plt()
    fig, axes = plt.subplots(2, len(panels), figsize=(5 * len(panels), 5), squeeze=False, sharex="col")
    for j, (label, t, y, yhat) in enumerate(panels):
        axes[0, j].plot(t, y, color="0.5", lw=1, label="measured")
        axes[0, j].plot(t, yhat, color="C3", lw=1, label="model")
        axes[0, j].set_title(label)
        axes[0, j].legend(loc="upper left")
        axes[1, j].plot(t, y - yhat, color="C0", lw=0.8)
        axes[1, j].axhline(0, color="k", lw=0.5)
        axes[1, j].set_xlabel("time (s)")
        axes[1, j].set_ylabel("error (mm)")
        axes[0, j].set_ylabel("displacement (mm)")
    fig.suptitle(title)
    return _save(fig, path)


class _ExpectedMisfit(logging.Filter):
    """Drops `fit`'s warning that its refinement ended at its start far above the noise (`identify._fit.NO_GAIN`):
    figs. 9-12 fit the paper's incomplete models on purpose (a static EUPI and a lag alone on a cascade's record), and
    the report shows their errors; the warning's advice (screen the start and structure) is for a user's own fit."""

    def filter(self, record: logging.LogRecord) -> bool:
        from ..identify._fit import NO_GAIN

        return NO_GAIN not in record.getMessage()


def _fit_as_the_paper(model, data, max_steps):
    """`smafl_jax.fit` with the paper's model as given, without the misfit warning (`_ExpectedMisfit`)."""
    import smafl_jax as sj

    log, quiet = logging.getLogger("smafl_jax.identify._fit"), _ExpectedMisfit()
    log.addFilter(quiet)
    try:
        return sj.fit(model, data, max_steps=max_steps)
    finally:
        log.removeFilter(quiet)


def section_eupi(recs, out, quick):
    """Paper figs. 9-10: the voltage-domain EUPI, fitted on the main loop, checked on the minor loop."""
    import smafl_jax as sj

    train, val = recs["main_loop"], recs["minor_loop"]
    model0 = sj.EUPI.from_range(0.0, float(max(train.u.max(), val.u.max())))
    res = _fit_as_the_paper(model0, train, 60 if quick else 300)
    m_tr = sj.metrics(train.y, sj.simulate(res.model, train.u, train.dt))
    m_va = sj.metrics(val.y, sj.simulate(res.model, val.u, val.dt))
    fig = _loop_figure(
        out / "fig09_10_eupi_loops.png",
        [
            ("main loop (train)", train.u, train.y, np.asarray(sj.simulate(res.model, train.u, train.dt))),
            ("minor loop (held out)", val.u, val.y, np.asarray(sj.simulate(res.model, val.u, val.dt))),
        ],
        "EUPI in the voltage domain (paper figs. 9-10)",
    )
    sj.save_model(
        out / "eupi_fit.json",
        res.model,
        metrics={"train": m_tr, "validation": m_va},
        solver={"converged": res.converged, "n_steps": res.n_steps, "message": res.message},
    )
    return {
        "train": m_tr,
        "validation": m_va,
        "fit": {"converged": res.converged, "n_steps": res.n_steps, "message": res.message},
        "figures": [fig],
    }


def section_joule(recs, out, quick):
    """Paper figs. 11-12: the Joule heat lag alone, U^2 -> displacement (eq. 7, plus an output offset)."""
    import jax.numpy as jnp

    import smafl_jax as sj

    rec = recs["steps"]
    paper = sj.JouleLag(
        thermal=sj.JouleThermal(k1=jnp.asarray(sj.PAPER_K1), k2=jnp.asarray(sj.PAPER_K2)), offset=jnp.asarray(float(rec.y[0]))
    )
    res = _fit_as_the_paper(paper, rec, 100 if quick else 400)
    yhat = np.asarray(sj.simulate(res.model, rec.u, rec.dt))
    m = sj.metrics(rec.y, yhat)
    y_paper = np.asarray(sj.simulate(paper, rec.u, rec.dt))
    m_paper = sj.metrics(rec.y, y_paper)
    fig = _time_figure(
        out / "fig11_12_joule.png",
        [("Joule lag fitted", rec.time, rec.y, yhat), ("paper's K1, K2 as printed", rec.time, rec.y, y_paper)],
        "Joule heat model, U^2 -> displacement (paper figs. 11-12)",
    )
    sj.save_model(out / "joule_fit.json", res.model, metrics={"train": m})
    return {
        "k1": float(res.model.thermal.k1),
        "k2": float(res.model.thermal.k2),
        "offset": float(res.model.offset),
        "metrics": m,
        "paper_params_metrics": m_paper,
        "fit": {"converged": res.converged, "n_steps": res.n_steps, "message": res.message},
        "figures": [fig],
    }


def section_cascade(recs, out, quick, truth):
    """Joint cascade fit on main loop + steps, validated on the minor loop; recovery of the truth."""
    import smafl_jax as sj

    train = [recs["main_loop"], recs["steps"]]
    val = recs["minor_loop"]
    model0 = sj.Cascade.from_range(float(max(r.u.max() for r in recs.values())))
    res = sj.fit(model0, train, max_steps=80 if quick else 400)
    yv = np.asarray(sj.simulate(res.model, val.u, val.dt))
    m_va = sj.metrics(val.y, yv)
    y_tr = [np.asarray(sj.simulate(res.model, r.u, r.dt)) for r in train]
    m_tr = sj.metrics(np.concatenate([r.y for r in train]), np.concatenate(y_tr))
    fig = _time_figure(
        out / "cascade_fit.png",
        [("steps (train)", train[1].time, train[1].y, y_tr[1]), ("minor loop (held out)", val.time, val.y, yv)],
        "Joint cascade fit: voltage -> heat -> EUPI -> displacement",
    )
    fit_doc = {
        "metrics": {"train": m_tr, "validation": m_va},
        "data": {
            "file": val.name,
            "path": val.path,
            "sha256": val.sha256,
            "input_column": val.input_name,
            "output_column": val.output_name,
            "sample_time_s": val.dt,
            "n_samples": len(val),
            "train_files": [r.name for r in train],
            "validation_files": [val.name],
        },
        "settings": {"model": "cascade", "quick": quick},
    }
    sj.save_model(out / "fit.json", res.model, **fit_doc)
    return {
        "model": res.model,
        "train": m_tr,
        "validation": m_va,
        "k1": float(res.model.thermal.k1),
        "k1_truth": float(truth.thermal.k1) if truth is not None else None,
        "fit": {"converged": res.converged, "n_steps": res.n_steps, "message": res.message},
        "figures": [fig],
        "fit_json": str(out / "fit.json"),
    }


def _metric_row(label, m, extra=()):
    return [label, m["rmse"], m["e_r_percent"], m["max_abs_error"], m["mean_abs_error"], *extra]


METRIC_HEADERS = ["", "RMSE (mm)", "e_r (%)", "max abs error (mm)", "mean abs error (mm)"]


def _write_eupi_joule_cascade(rep, s1, s2, s3):
    P = PAPER_VALUES
    rep.heading("1. EUPI hysteresis model (paper figs. 9-10)")
    rep.text(
        "The EUPI of eq. (2) fitted in the voltage domain, as the paper does, on the bundled main loop "
        "(two slow 0 -> 7.4 -> 0 V cycles) and checked on the held-out minor-loop record. Gains start from "
        "the paper's constrained least squares (bounded-variable least squares: operator gains >= 0); with thresholds "
        "and tilts fixed, that solution is already the joint optimum."
    )
    rep.table(
        METRIC_HEADERS + ["paper e_r (%)"],
        [
            _metric_row("main loop, train", s1["train"], [P["eupi_e_r_percent"]]),
            _metric_row("minor loop, held out", s1["validation"], ["–"]),
        ],
    )
    for f in s1["figures"]:
        rep.figure(f, "EUPI model over the measured loops (left: train, right: held out)")
    verdict = "reproduced in kind" if s1["train"]["e_r_percent"] < 2 * P["eupi_e_r_percent"] else "not reproduced"
    rep.text(
        f"Verdict: {verdict}. A rate-independent EUPI reaches e_r = {fmt(s1['train']['e_r_percent'], 3)} % here "
        f"(paper: 6.3 % on its own rig). On these records the residual left is the thermal lag, which the "
        "voltage-domain EUPI cannot represent; section 3 removes it."
    )
    rep.heading("2. Joule heat model (paper figs. 11-12, eq. 7)")
    rep.text(
        "The first-order lag from U^2 to displacement (eq. 7, with an output offset because the joint does not rest "
        "at 0 mm) fitted alone on the step record, next to the paper's identified values. The paper's K2/K1 = 0.836 per V^2 would put the displacement at 46 mm for 7.4 V on a "
        "joint that moves at most 6 mm, so the paper's M' cannot be U^2 in volts as printed; its K1 (the time "
        "constant) is the comparable quantity."
    )
    rep.table(
        ["", "K1 (1/s)", "K2", "time constant 1/K1 (s)", "max abs error (mm)", "RMSE (mm)"],
        [
            ["this run (fitted)", s2["k1"], s2["k2"], 1 / s2["k1"], s2["metrics"]["max_abs_error"], s2["metrics"]["rmse"]],
            [
                "paper's K1, K2 on this record",
                P["k1"],
                P["k2"],
                1 / P["k1"],
                s2["paper_params_metrics"]["max_abs_error"],
                s2["paper_params_metrics"]["rmse"],
            ],
            ["paper (own rig)", P["k1"], P["k2"], 1 / P["k1"], P["joule_max_error_mm"], "–"],
        ],
    )
    for f in s2["figures"]:
        rep.figure(f, "Joule model alone: fitted (left) and with the paper's K1, K2 (right)")
    rep.text(
        f"Verdict: the lag alone leaves a max error of {fmt(s2['metrics']['max_abs_error'], 3)} mm on this record "
        "(paper: 0.510 mm on its rig): a linear lag from U^2 cannot carry the hysteresis and the saturation of the "
        "actuator, so its fitted K1 is biased; the cascade below identifies K1 with the hysteresis in place."
    )
    rep.heading("3. Joint cascade fit: voltage -> heat -> EUPI -> displacement")
    truth_txt = (
        f" The bundled data were generated with K1 = {fmt(s3['k1_truth'])} 1/s; the fit recovers "
        f"K1 = {fmt(s3['k1'])} 1/s ({fmt(100 * (s3['k1'] / s3['k1_truth'] - 1), 3)} %)."
        if s3.get("k1_truth")
        else ""
    )
    rep.text(
        "Thermal K1 and all EUPI gains fitted jointly on the main loop and the step record; the minor-loop record is "
        "held out. K2 is not identifiable from displacement in the cascade (the hysteresis sees sqrt(theta K1/K2), "
        "in which K2 cancels) and is held at the paper's value." + truth_txt
    )
    rep.table(
        METRIC_HEADERS,
        [_metric_row("train (main loop + steps)", s3["train"]), _metric_row("held out (minor loop)", s3["validation"])],
    )
    for f in s3["figures"]:
        rep.figure(f, "Cascade: measured vs model over time, with the error below")


def fmt(x, digits=4):
    from ..report._reportdoc import fmt as _fmt

    return _fmt(x, digits)


CONTROL_ASSUMPTIONS = [
    "sample time 0.01 s and 40 s records (the paper gives neither); e_mean (eq. 8) over the whole record and "
    "over t >= 20 s ('settled')",
    "gains Kp = 35, Ki = 20, Kd = 0, K = 10 (the paper's simulation values); drive clipped to 0..7.4 V with "
    "conditional-integration anti-windup",
    "plant = the bundled data's true cascade (datasets/truth.json) at rest at 0 V; the I-I compensator runs on the "
    "EUPI identified in section 3 (so it is an identified model, not the plant); noise-free sensor",
    "a slow sine (1/20 of the paper's frequency, 2 periods, settled = 2nd period) is added because the paper's "
    "sine cannot be followed through a ~16 s thermal lag with 0..7.4 V",
]


def section_control(plant, identified, out, quick):
    """Paper section 4.2: PID vs composite PID on the sine and step references (figs. 14-15)."""
    import jax.numpy as jnp

    from ..control._control import (
        PAPER_GAINS,
        PID,
        ClosedLoop,
        IICompensator,
        simulate_closed_loop,
        sine_reference,
        step_reference,
    )

    dt, T = 0.01, 40.0
    slow_w = 3 * np.pi / 10 / 20
    refs = {
        "sine": (sine_reference(T, dt), 20.0),
        "step": (step_reference(T, dt), 20.0),
        "slow sine": (sine_reference(2 * 2 * np.pi / slow_w, dt, omega=slow_w), 2 * np.pi / slow_w),
    }
    skipped = []
    if quick:
        refs.pop("slow sine")
        skipped.append("the slow-sine reference (run without --quick)")
    g = PAPER_GAINS
    rows, trajs = [], {}
    for rname, (ref, settle) in refs.items():
        for ctrl in ("pid", "composite"):
            comp = IICompensator(identified, g["K"]) if ctrl == "composite" else None
            row = {"reference": rname, "controller": ctrl}
            for window, start in (("full", 0.0), ("settled", settle)):
                loop = ClosedLoop(
                    plant=plant,
                    pid=PID(g["kp"], g["ki"], g["kd"]),
                    reference=jnp.asarray(ref),
                    compensator=comp,
                    eval_start=jnp.asarray(start),
                )
                m, tr = simulate_closed_loop(loop, dt)
                row[f"e_mean_{window}_mm"] = float(m["e_mean_mm"])
                if window == "full":
                    row.update(
                        rmse_mm=float(m["rmse_mm"]),
                        max_abs_error_mm=float(m["max_abs_error_mm"]),
                        saturated_fraction=float(m["saturated_fraction"]),
                    )
                    trajs[(rname, ctrl)] = {k: np.asarray(v) for k, v in tr.items()}
            row["paper_sim_e_mean_mm"] = PAPER_VALUES["e_mean_sim"].get((ctrl, rname))
            row["paper_exp_e_mean_mm"] = PAPER_VALUES["e_mean_exp"].get((ctrl, rname))
            rows.append(row)
    plt = _plt()
    figs = []
    for i, rname in enumerate(refs):
        fig, (a1, a2) = plt.subplots(2, 1, figsize=(8, 5.5), sharex=True)
        tr0 = trajs[(rname, "pid")]
        a1.plot(tr0["time_s"], refs[rname][0], "k--", lw=1, label="reference")
        for ctrl in ("pid", "composite"):
            tr = trajs[(rname, ctrl)]
            a1.plot(tr["time_s"], tr["y"], lw=1, label=ctrl)
            a2.plot(tr["time_s"], tr["error"], lw=1, label=ctrl)
        a1.set_ylabel("displacement (mm)")
        a2.set_ylabel("error (mm)")
        a2.set_xlabel("time (s)")
        a1.legend()
        fig.suptitle(f"{rname} tracking: PID vs composite PID")
        figs.append(_save(fig, out / f"fig{14 + i}_control_{rname.replace(' ', '_')}.png"))
    from .._io import atomic_write_json

    atomic_write_json(out / "control_metrics.json", {"rows": rows, "assumptions": CONTROL_ASSUMPTIONS, "dt_s": dt})
    ranking = {r: control_ranking([row for row in rows if row["reference"] == r]) for r in refs}
    wins = {r: v["verdict"] == "composite" for r, v in ranking.items()}
    return {"rows": rows, "figures": figs, "composite_wins": wins, "ranking": ranking, "skipped": skipped}


#: Relative e_mean difference below which two controllers are called a tie (the closed loop saturates most of
#: the time, and a few percent move with the record length and the sample time, which the paper does not give).
TIE_MARGIN = 0.05
#: e_mean below which both controllers count as on target (mm): far under the bundled sensor's 16-bit resolution
#: scale and the paper's smallest simulated value (0.0004 mm), where a relative difference means nothing.
E_MEAN_FLOOR_MM = 1e-4


def control_ranking(rows):
    """Which controller has the lower e_mean on one reference, over the whole record AND the settled window.

    ``verdict``: ``"composite"`` or ``"pid"`` when that controller is lower by more than `TIE_MARGIN` in both
    windows, else ``"tie"`` (within the margin, or the windows disagree).  ``margins``: (PID - composite) / PID.
    """
    e = {(r["controller"], w): r[f"e_mean_{w}_mm"] for r in rows for w in ("full", "settled")}
    margins = {}
    for w in ("full", "settled"):
        pid, comp = e[("pid", w)], e[("composite", w)]
        # both on target: a tie (None), not a relative difference of two round-off-sized numbers
        margins[w] = None if max(pid, comp) < E_MEAN_FLOOR_MM else (pid - comp) / pid
    if all(m is not None and m > TIE_MARGIN for m in margins.values()):
        verdict = "composite"
    elif all(m is not None and m < -TIE_MARGIN for m in margins.values()):
        verdict = "pid"
    else:
        verdict = "tie"
    return {"verdict": verdict, "margins": margins}


def _margin_text(m):
    return f"both < {E_MEAN_FLOOR_MM:g} mm" if m is None else f"{100 * m:+.1f} %"


def _ranking_text(ref, rk):
    m = rk["margins"]
    pct = f"composite lower by {_margin_text(m['full'])} (whole record), {_margin_text(m['settled'])} (settled)"
    if rk["verdict"] == "composite":
        return f"{ref}: composite better ({pct})"
    if rk["verdict"] == "pid":
        return f"{ref}: PID better ({pct})"
    return f"{ref}: no clear winner ({pct}; a tie is within {100 * TIE_MARGIN:.0f} % or windows that disagree)"


def _write_control(rep, s5):
    rep.heading("5. Closed-loop control: PID vs composite PID (paper figs. 14-15)")
    skipped = s5.get("skipped") or []
    rep.bullets(
        [a for a in CONTROL_ASSUMPTIONS if not (skipped and a.startswith("a slow sine"))]
        + [f"skipped in this --quick run: {x}" for x in skipped]
    )
    rep.table(
        [
            "reference",
            "controller",
            "e_mean (mm)",
            "e_mean settled (mm)",
            "paper sim (mm)",
            "paper exp (mm)",
            "RMSE (mm)",
            "saturated",
        ],
        [
            [
                r["reference"],
                r["controller"],
                r["e_mean_full_mm"],
                r["e_mean_settled_mm"],
                r["paper_sim_e_mean_mm"],
                r["paper_exp_e_mean_mm"],
                r["rmse_mm"],
                r["saturated_fraction"],
            ]
            for r in s5["rows"]
        ],
    )
    for f in s5["figures"]:
        rep.figure(f, f"{Path(f).stem.split('_', 2)[-1].replace('_', ' ')}: tracking (top) and error (bottom)")
    rk = s5["ranking"]
    n_won = sum(v["verdict"] == "composite" for v in rk.values())
    n_lost = sum(v["verdict"] == "pid" for v in rk.values())
    if n_won == len(rk):
        overall = "reproduced"
    elif n_lost:
        overall = "not reproduced (PID better on " + ", ".join(r for r, v in rk.items() if v["verdict"] == "pid") + ")"
    elif n_won:
        overall = "partly reproduced"
    else:
        overall = "not resolved: no clear winner on any reference"
    rep.text(
        f"Verdict: the paper's ranking (composite better than PID on every reference) is {overall} here. "
        + "; ".join(_ranking_text(r, v) for r, v in rk.items())
        + ". The absolute e_mean values are far above the paper's simulated 0.0004-0.0030 mm: the paper's 1 mm sine "
        "at 0.94 rad/s through a ~16-20 s thermal lag needs the drive to swing beyond 0..7.4 V (it saturates most "
        "of the time, see the last column), so no controller limited to positive voltages can reach the paper's "
        "simulated numbers; the paper does not state its sample time, record length or whether its simulated "
        "plant was saturated."
    )


def _versions():
    import importlib.metadata as md

    out = {}
    for name in ("smafl-jax", "jax", "equinox", "optimistix", "jaxopt", "emcee", "numpy", "matplotlib"):
        try:
            out[name] = md.version(name)
        except md.PackageNotFoundError:
            out[name] = None
    return out


def run_paper(out, *, quick=False, datasets=None, real=None, seed=0):
    """Run every section on the bundled records and write ``report.md``, ``report.html`` and ``paper.json``."""
    import platform

    import smafl_jax as sj

    from .._io import atomic_write_json, prepare_out_dir
    from ..report._reportdoc import Report

    out = prepare_out_dir(out)
    datasets = Path(datasets) if datasets is not None else default_datasets_dir()
    real = Path(real) if real is not None else default_real_dir()
    names = ["main_loop", "minor_loop", "steps"]
    missing = [n for n in names if not (datasets / f"{n}.csv").exists()]
    if missing:
        raise sj.UserInputError(f"{datasets}: bundled records missing: {missing} (run python datasets/generate.py)")
    t_start = time.perf_counter()
    progress = _Progress(len(SECTIONS) + 1)
    recs = {n: sj.load_record(datasets / f"{n}.csv") for n in names}
    truth = sj.load_model(datasets / "truth.json") if (datasets / "truth.json").exists() else None
    ctx = {"recs": recs, "truth": truth, "out": out, "quick": quick, "real": real, "seed": seed, "results": {}}
    for key, title, fn in SECTIONS:
        progress(title)
        ctx["results"][key] = fn(ctx)
    progress("writing the report")
    rep = Report("smafl-jax reproduction of Xiang et al. (2017), SMA-fishing-line actuator")
    results = ctx["results"]
    _write_summary(rep, results, quick, time.perf_counter() - t_start)
    _write_eupi_joule_cascade(rep, results["eupi"], results["joule"], results["cascade"])
    for key, writer in WRITERS:
        if key in results:
            writer(rep, results[key])
    rep.heading("Provenance")
    rep.text(
        f"Generated by `smafl paper{' --quick' if quick else ''}` on {time.strftime('%Y-%m-%d %H:%M')} "
        f"({platform.platform()}, {platform.python_version()}); bundled records from `datasets/` (synthetic, "
        "seeded, see datasets/README.md). Paper: Xiang et al., Smart Mater. Struct. 26 (2017) 037004, "
        "doi:10.1088/1361-665X/aa5b03. Real data, where used, was read in place from its folder with its "
        "provenance in that folder's README."
    )
    rep.write(out / "report.md", out / "report.html")
    summary = {k: _strip(v) for k, v in results.items()}
    summary["quick"] = quick
    summary["elapsed_s"] = time.perf_counter() - t_start
    summary["versions"] = _versions()
    summary["paper_values"] = {
        k: (v if not isinstance(v, dict) else {f"{a}/{b}": x for (a, b), x in v.items()}) for k, v in PAPER_VALUES.items()
    }
    atomic_write_json(out / "paper.json", summary)
    summary["out"] = str(out)
    return summary


def _strip(v):
    """Results without model objects (for paper.json)."""
    if isinstance(v, dict):
        return {k: _strip(x) for k, x in v.items() if k != "model" and not hasattr(x, "simulate")}
    if isinstance(v, (list, tuple)):
        return [_strip(x) for x in v]
    if isinstance(v, Path):
        return v.name
    return v


#: What `smafl paper --quick` leaves out (said in the report's first paragraph and in the sections concerned).
QUICK_SKIPS = [
    "the slow-sine control case (section 5)",
    "two diagnoses (section 6): the bundled drives with an undeclared effect, and the real NiTi water-bath record",
    "and it tests each diagnosis candidate on 4 null records instead of 10 (a cruder false-positive threshold) and "
    "does not refit the diagnosed models on the whole record (the diagnosis folders hold the split fits)",
    "nor refine the diagnosis base and candidates jointly (thresholds, tilts, operator memory; `smafl diagnose`'s "
    "default): it fits the 3 effects with the best score-test evidence on the profiled base",
]


def _write_summary(rep, r, quick, elapsed):
    rep.text(
        "Every number below was computed by this run on the bundled synthetic records (generated from a known "
        "cascade with 16-bit sensor noise), except the paper's own values, which are labelled 'paper'. "
        + (
            "This is the `--quick` variant: fewer solver steps and samples, and it skips "
            + "; ".join(QUICK_SKIPS)
            + ". Run `smafl paper` without --quick for all of them."
            if quick
            else ""
        )
        + f" Run time: {elapsed:.0f} s."
    )
    rows = [
        [
            "EUPI error ratio e_r (eq. 3)",
            "6.3 %",
            f"{fmt(r['eupi']['train']['e_r_percent'], 3)} % (train), {fmt(r['eupi']['validation']['e_r_percent'], 3)} % (held out)",
            "in kind",
        ],
        [
            "Joule model K1 (1/s)",
            "0.04988",
            f"{fmt(r['cascade']['k1'])} (cascade), {fmt(r['joule']['k1'])} (lag alone)",
            "own rig differs; truth recovered" if r["cascade"].get("k1_truth") else "–",
        ],
        ["Joule model max error (mm)", "0.510", fmt(r["joule"]["metrics"]["max_abs_error"], 3), "lag alone is too simple here"],
        ["cascade held-out e_r", "–", f"{fmt(r['cascade']['validation']['e_r_percent'], 3)} %", "new"],
    ]
    if "control" in r:
        c = {(x["controller"], x["reference"]): x["e_mean_full_mm"] for x in r["control"]["rows"]}
        status = {"composite": "ranking reproduced", "pid": "ranking not reproduced (PID better)", "tie": "no clear winner"}
        for ref in ("sine", "step"):
            rk = r["control"]["ranking"][ref]
            rows.append(
                [
                    f"e_mean {ref}: composite / PID (mm)",
                    f"{PAPER_VALUES['e_mean_sim'][('composite', ref)]} / {PAPER_VALUES['e_mean_sim'][('pid', ref)]}",
                    f"{fmt(c[('composite', ref)], 3)} / {fmt(c[('pid', ref)], 3)}",
                    f"{status[rk['verdict']]} (composite lower by {_margin_text(rk['margins']['full'])} whole, "
                    f"{_margin_text(rk['margins']['settled'])} settled)",
                ]
            )
    for key, summarise in SUMMARY_ROWS:
        if key in r:
            rows += summarise(r[key])
    rep.heading("What was reproduced (one page)")
    rep.table(["claim", "paper", "this run", "status"], rows)


# Section registry: (key, progress title, function(ctx) -> results).
SECTIONS = [
    ("eupi", "EUPI identification (figs. 9-10)", lambda c: section_eupi(c["recs"], c["out"], c["quick"])),
    ("joule", "Joule heat model (figs. 11-12)", lambda c: section_joule(c["recs"], c["out"], c["quick"])),
    ("cascade", "joint cascade fit", lambda c: section_cascade(c["recs"], c["out"], c["quick"], c["truth"])),
    (
        "control",
        "closed-loop control (figs. 14-15)",
        lambda c: section_control(
            c["truth"] or c["results"]["cascade"]["model"], c["results"]["cascade"]["model"], c["out"], c["quick"]
        ),
    ),
]
WRITERS = [("control", _write_control)]
SUMMARY_ROWS = []


def section_diagnosis(recs, out, quick, real):
    """Residual diagnosis: the bundled record (nothing hidden in it) and, when present, real SMA data."""
    import dataclasses

    import smafl_jax as sj

    from .._io import prepare_out_dir
    from ..diagnosis._diagnose import diagnose, synthetic_effect_record
    from ..report._report import write_diagnosis
    from ..report._reportdoc import unit_of

    jobs = [("bundled main loop (synthetic, no hidden effect)", recs["main_loop"])]
    if not quick:
        # The bundled drives with an effect the diagnosis is not told about (seeded strength).
        truth = sj.load_model(default_datasets_dir() / "truth.json")
        drives = {k: (r.time, r.u, "") for k, r in recs.items()}
        hidden, _ = synthetic_effect_record(truth, drives, "creep", seed=7, dt=recs["main_loop"].dt)
        hidden = dataclasses.replace(hidden, path="synthetic_hidden_effect.csv")
        jobs.append(("bundled drives + an undeclared effect (creep, seeded)", hidden))
    forc = Path(real) / "sma_wing_forc_train.csv"
    if forc.exists():
        jobs.append(
            ("real SMA wire, reversal branches (measured)", sj.load_record(forc, input="voltage_V", output="displacement"))
        )
    water = Path(real) / "niti_wire_water_step_01.csv"
    if water.exists() and not quick:
        jobs.append(
            (
                "real NiTi wire, water-bath temperature steps (measured)",
                sj.load_record(water, input="temperature_front_C", output="length_signal"),
            )
        )
    rows = []
    from .._progress import LOGGER, Steps

    steps = Steps("residual diagnosis", len(jobs), unit="records")
    for label, rec in jobs:
        LOGGER.info(f"  residual diagnosis: {label} ({rec.name}, {len(rec)} samples)")
        sub = prepare_out_dir(out / f"diagnosis_{rec.name}", announce=False)
        # --quick: 4 null records per candidate instead of 10 (the calibrated rule's cost grows with them;
        # the threshold is then a cruder normal approximation, which the diagnosis report states)
        # --quick: no whole-record refit either (the report uses the split fits' held-out figures; the folder then
        # holds the split fits as base_fit.json / extended_fit.json)
        # --quick: no symmetric refinement either (the 3 candidates with the best score-test evidence on the profiled
        # base, as before it; with it the two quick diagnoses took 4.5 min instead of about 1 on 2 cores)
        diag = diagnose(rec, verbose=False, refit=not quick, **({"n_null": 4, "refine": False} if quick else {}))
        write_diagnosis(sub, rec, diag)
        rows.append(
            {
                "record": label,
                "file": rec.name,
                "selected": list(diag.selected),
                "base_heldout_rmse": diag.report["base"]["heldout_rmse"],
                "extended_heldout_rmse": diag.report["extended"]["heldout_rmse"],
                "base_heldout_e_r_percent": diag.report["base"]["heldout"]["e_r_percent"],
                "extended_heldout_e_r_percent": diag.report["extended"]["heldout"]["e_r_percent"],
                "split": diag.split.kind,
                "output_unit": unit_of(rec.output_name, getattr(rec, "units", None)) or f"units of '{rec.output_name}'",
                "folder": sub.name,
                "figures": sorted(str(p) for p in sub.glob("*.png")),
            }
        )
        steps.advance(note=rec.name)
    skipped = []
    if quick:
        skipped.append("the bundled drives with an undeclared effect (creep)")
        if water.exists():
            skipped.append(f"the real NiTi water-bath record {water.name}")
    return {
        "rows": rows,
        "real_data_present": forc.exists(),
        "real_data_dir": str(real),
        "skipped": skipped,
        "n_null": 4 if quick else 10,
    }


def _write_diagnosis(rep, s6):
    rep.heading("6. Residual diagnosis: finding what the model lacks")
    rep.text(
        "`smafl diagnose` fits the base model on a training block, tests its residuals (whiteness, Ljung-Box, "
        "correlation with candidate signals), ranks the catalogue of physical effects by residual evidence and fits "
        "the plausible ones. An effect is kept only if it cuts the held-out RMSE by at least 5 % without raising the "
        "held-out max error, helps in all (or all but one) of the cross-validation folds, and beats the gains the same "
        "effect reaches on null records simulated without it (the calibrated rule; details and per-fold and null "
        "gains in each diagnosis folder's report.md). It is not told which effect, if any, is in the data."
    )
    rep.table(
        ["record", "selected", "held-out RMSE before", "after", "RMSE unit", "held-out e_r % before", "after"],
        [
            [
                r["record"],
                ", ".join(r["selected"]) or "none",
                r["base_heldout_rmse"],
                r["extended_heldout_rmse"],
                r.get("output_unit", "–"),
                r["base_heldout_e_r_percent"],
                r["extended_heldout_e_r_percent"],
            ]
            for r in s6["rows"]
        ],
    )
    for r in s6["rows"]:
        for f in r["figures"]:
            if "before" in Path(f).name or "after" in Path(f).name:
                rep.figure(f, f"{r['file']}: {Path(f).stem.replace('_', ' ')}")
    for r in s6["rows"]:
        if r["file"] == "sma_wing_forc_train":
            e = r["extended_heldout_e_r_percent"]
            rep.text(
                f"Real SMA reversal branches: held-out e_r {fmt(r['base_heldout_e_r_percent'], 3)} % with the paper's EUPI, "
                f"{fmt(e, 3)} % after the selected effects ({', '.join(r['selected']) or 'none'}); the toolkit's target of "
                f"5 % is {'reached' if e < 5 else 'not reached'} (the paper's 6.3 % was on its own, gentler loop)."
            )
    if s6.get("skipped"):
        rep.text(
            "Skipped in this --quick run (run without --quick for them): "
            + "; ".join(s6["skipped"])
            + f". Each candidate effect was tested on {s6.get('n_null', 4)} null records (10 in the full run), and the "
            "models in the diagnosis folders are the split fits (the full run also refits them on the whole record)."
        )
    if not s6["real_data_present"]:
        rep.text(
            f"The real measured records were not found (looked for {s6.get('real_data_dir', '../shared/data/real')}/"
            "sma_wing_forc_train.csv; `--real-data FOLDER` names another folder), so only the bundled record was diagnosed."
        )


def _summary_diagnosis(s6):
    return [
        [
            f"diagnosis: {r['file']}",
            "–",
            f"{', '.join(r['selected']) or 'none'}; held-out e_r {fmt(r['base_heldout_e_r_percent'], 3)} -> {fmt(r['extended_heldout_e_r_percent'], 3)} %",
            "new",
        ]
        for r in s6["rows"]
    ]


SECTIONS.append(("diagnosis", "residual diagnosis", lambda c: section_diagnosis(c["recs"], c["out"], c["quick"], c["real"])))
WRITERS.append(("diagnosis", _write_diagnosis))
SUMMARY_ROWS.append(("diagnosis", _summary_diagnosis))


def section_bayes(recs, out, quick, fit_json, seed):
    """Posterior of the cascade (emcee, gains marginalised) with the held-out minor loop on top."""
    from ..workflows import sample_posterior

    sub = out / "posterior"
    # --quick: 200 steps (a smoke run; its summary says the chain is too short): on the bundled main loop K1 mean and sd
    # and the held-out band coverage agree with 400 steps to < 1 %, and the section takes about 10 s less on 2 cores
    steps = 200 if quick else 3000
    summary = sample_posterior(
        recs["main_loop"].path, str(fit_json), out=sub, heldout=recs["minor_loop"].path, steps=steps, seed=seed, restart=True
    ).summary
    return {
        "summary": summary,
        "steps": steps,
        "figures": [
            str(sub / f) for f in ("predictive_time.png", "predictive_loop.png", "corner.png", "trace.png") if (sub / f).exists()
        ],
    }


def _write_bayes(rep, s4):
    s = s4["summary"]
    rep.heading("4. Posterior uncertainty (emcee)")
    rep.text(
        f"emcee ensemble sampler, {s['n_walkers']} walkers x {s['n_steps']} steps (burn-in {s['burn']}), one jitted "
        "vmapped log-density for all walkers, conditioned on the main loop; the EUPI gains are marginalised "
        "analytically (Gaussian prior), so the chain samples the thermal K1 and the noise scale. Acceptance "
        f"fraction {fmt(s['acceptance_fraction'], 3)}, max autocorrelation time {fmt(s['autocorr_time_max'], 3)} steps."
    )
    rows = [[name, p["mean"], p["sd"], p["q025"], p["q975"], p.get("ess")] for name, p in s["parameters"].items()]
    for name, p in s.get("derived", {}).items():
        rows.append(
            [name, p.get("mean"), p.get("sd"), p.get("q025"), p.get("q975"), "–"]
            if "mean" in p
            else [name, "not identified", "–", "–", "–", "–"]
        )
    rep.table(["parameter", "mean", "sd", "2.5 %", "97.5 %", "ESS"], rows)
    cover = s.get("heldout_coverage_95")
    if cover is not None:
        rep.text(f"Held-out minor-loop points inside the 95 % posterior-predictive band: {fmt(100 * cover, 3)} %.")
    for w in s.get("warnings", []):
        rep.text(f"Warning from the diagnostics: {w}")
    for f in s4["figures"]:
        rep.figure(f, Path(f).stem.replace("_", " "))


def _summary_bayes(s4):
    p = s4["summary"]["parameters"].get("thermal.k1")
    if not p:
        return []
    short = [w for w in s4["summary"].get("warnings", []) if "too short" in w]
    return [
        [
            "posterior K1, 95 % interval (1/s)",
            "– (point estimate only)",
            f"{fmt(p['mean'])} [{fmt(p['q025'])}, {fmt(p['q975'])}]",
            "indicative only: the chain is too short (section 4)" if short else "new",
        ]
    ]


SECTIONS.insert(
    3,
    (
        "bayes",
        "posterior sampling",
        lambda c: section_bayes(c["recs"], c["out"], c["quick"], c["results"]["cascade"]["fit_json"], c["seed"]),
    ),
)
WRITERS.insert(0, ("bayes", _write_bayes))
SUMMARY_ROWS.insert(0, ("bayes", _summary_bayes))
