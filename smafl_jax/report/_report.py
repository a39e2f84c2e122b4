"""Writing a diagnosis: diagnosis.json, base_fit.json / extended_fit.json (fit.json format), report.md, plots."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .._io import atomic_savefig, atomic_write_json, atomic_write_text, save_model
from ..models._range import EFFECTIVE_RULE, effective_range, hysteresis_values, trained_branches_of, value_range
from ._provenance import record_data, versions
from ._reportdoc import axis_label, unit_of

if TYPE_CHECKING:
    from ..data._data import Record
    from ..diagnosis._result import Diagnosis

__all__ = ["write_diagnosis", "versions"]


def _trained_range(rec, split, model, deployed):
    """``data`` entries of a saved model: the input range it was fitted on (and, for a model with a thermal stage, the
    range of its hysteresis input), so that `smafl simulate` / `control` / `sweep` check a new drive against them."""
    if deployed:
        segs, rule = (
            [(np.asarray(rec.u, float), np.ones(len(rec), bool))],
            "min and max of the input over the whole record (refitted on it)",
        )
    else:
        segs = [(np.asarray(s.u, float), np.asarray(s.mask, bool)) for s in split.train]
        rule = "min and max of the input over the training samples of the split"
    out = {"input_range": value_range(np.concatenate([u[m] for u, m in segs])), "input_range_rule": rule}
    eff = effective_range([(model, u, rec.dt, m) for u, m in segs])
    if eff is not None:
        out["effective_input_range"] = eff
        out["effective_input_range_rule"] = EFFECTIVE_RULE
    xs = [hysteresis_values(model, u, rec.dt) for u, _ in segs]  # a direct-input hysteresis: the input itself
    if all(x is not None and np.all(np.isfinite(x)) for x in xs) and any(m.any() for _, m in segs):
        # each segment is its own trajectory (joining them would invent a move between unrelated histories)
        out["trained_branches"] = trained_branches_of([(x, m) for x, (_, m) in zip(xs, segs)])
    return out


def _fit_doc(rec, res, which, split, model, deployed=False):
    part = res["base"] if which == "base" else res["extended"]
    extra = {}
    if deployed:
        # the deployed model has no held-out data left: its validation figures are those of the same structure fitted on the split
        extra = {
            "refit": {
                "fitted_on": res["deployed"]["fitted_on"],
                "segments": res["deployed"]["segments"],
                "rmse_all_samples": res["deployed"][f"{'base' if which == 'base' else 'extended'}_rmse_all"],
                "validation_metrics_from": f"{which}_fit_train.json (same structure fitted on the training split only)",
            }
        }
    return {
        "metrics": {"train": part["train"], "validation": part["heldout"]},
        **extra,
        # the record's provenance as in fit.json; an in-memory record keeps its name as "file"
        "data": {**record_data(rec), **({} if rec.path else {"file": rec.name}), **_trained_range(rec, split, model, deployed)},
        "settings": {
            "command": "diagnose",
            "split": res["split"],
            "effects": part.get("effects", []),
            "base_rule": res["base"]["rule"],
        },
        "versions": versions(),
        "solver": {
            "method": "variable projection: bounded least squares for the EUPI gains, Nelder-Mead for thermal/effect parameters"
        },
    }


def _plot(path, split, model_sim, title, ylabel="output"):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..diagnosis._residuals import autocorrelation

    fig, ax = plt.subplots(3, 1, figsize=(10, 8), layout="constrained")
    t0 = 0.0
    all_e = []
    for kind, segs in (("train", split.train), ("held-out", split.test)):
        for s in segs:
            yh = model_sim(s)
            x = t0 + np.arange(int(s.mask.sum()))
            e = (s.y - yh)[s.mask]
            all_e.append(e)
            color = "C0" if kind == "train" else "C3"
            ax[0].plot(x, s.y[s.mask], color="k", lw=0.8)
            ax[0].plot(x, yh[s.mask], color=color, lw=0.8)
            ax[1].plot(x, e, color=color, lw=0.8, label=kind if s is segs[0] else None)
            t0 = x[-1] + 1 if x.size else t0
    two_lines = lambda label: label.replace(" (", "\n(", 1)  # name over unit: long labels stay inside the figure
    ax[0].set_ylabel(two_lines(ylabel))
    ax[0].set_title("black: measured; blue: model on training blocks; red: model on held-out blocks", fontsize=9)
    ax[1].set_ylabel(two_lines(ylabel.replace(ylabel.split(" (")[0], "residual", 1)))
    ax[1].legend(loc="upper right")
    ax[1].set_xlabel("sample (train blocks, then held-out blocks)")
    e = np.concatenate(all_e)
    rho = autocorrelation(e, min(100, e.size // 3))
    ax[2].bar(np.arange(rho.size), rho, width=0.8)
    b = 1.96 / np.sqrt(e.size)
    ax[2].axhline(b, color="r", ls="--", lw=0.8)
    ax[2].axhline(-b, color="r", ls="--", lw=0.8)
    ax[2].set_ylabel("residual autocorrelation (unitless)")
    ax[2].set_xlabel("lag (samples)")
    fig.suptitle(title)
    atomic_savefig(fig, path)
    plt.close(fig)


def _noise_lines(noise):
    """The diagnosis' RMSEs in units of the output noise estimated from the data (diagnosis.json ``noise``)."""
    if not noise or not noise.get("sd"):
        return []

    def r(k):
        return "n/a" if noise.get(k) is None else f"{noise[k]:.3g}x"

    return [
        "",
        f"In units of the output noise SD ({noise['sd']:.4g}, estimated from the data: {noise['method']}): base "
        f"{r('base_train_ratio')} train, {r('base_heldout_ratio')} held out; extended {r('extended_train_ratio')} train, "
        f"{r('extended_heldout_ratio')} held out."
        + (
            f" The base leaves {noise['base_structure_left_sd']:.2g} noise SD of structure on its training samples "
            "(RMS of the misfit above the noise)."
            if noise.get("base_structure_left_sd") is not None
            else ""
        ),
    ]


def _reference_lines(ref):
    """The table row of `smafl fit`'s default model on the same split, where the diagnosis fitted it (`_reference`)."""
    if not ref or ref.get("heldout_rmse") is None:
        return []
    return [f"| reference: {ref['rule']} | - | {ref['heldout_rmse']:.4g} | - |"]


def _report_md(rec, res):
    b, x = res["base"], res["extended"]
    u = unit_of(rec.output_name, getattr(rec, "units", None)) or f"units of '{rec.output_name}'"
    L = [
        f"# Diagnosis of `{rec.name}`",
        "",
        f"- Base model: {b['rule']}",
        f"- Split: {res['split']['rule']}",
        *[
            f"- **Warning:** {res['split'][k]['warning']}"
            for k in ("coverage", "state_coverage")
            if (res["split"].get(k) or {}).get("warning")
        ],
        f"- Selected effect(s): **{', '.join(res['selected']) or 'none'}**",
        "",
        f"| model | train RMSE ({u}) | held-out RMSE ({u}) | held-out e_r (%) |",
        "|---|---|---|---|",
        f"| base | {b['train_rmse']:.4g} | {b['heldout_rmse']:.4g} | {b['heldout']['e_r_percent']:.2f} |",
        f"| extended ({', '.join(res['selected']) or 'none'}) | {x['train_rmse']:.4g} | {x['heldout_rmse']:.4g} | {x['heldout']['e_r_percent']:.2f} |",
        *_reference_lines(b.get("reference_fit")),
        *_noise_lines(res.get("noise")),
        "",
        "## Base residuals",
        "",
    ]
    for part in ("train", "heldout"):
        w = res["residuals"][part]["whiteness"]
        lb = w["ljung_box"] or {}
        L.append(
            f"- {part}: Ljung-Box Q = {lb.get('Q', float('nan')):.1f} (p = {lb.get('p_value', float('nan')):.2g}); "
            f"{100 * w['acf_fraction_outside']:.0f} % of ACF lags outside +-{w['acf_bound']:.3f}; "
            f"max |ccf with input| {w['ccf_max_abs']:.2f} at lag {w['ccf_argmax_lag']}"
        )
    corr = res["residuals"]["train"]["signal_correlations"]
    L += [
        "",
        "Correlation of the training residual with candidate signals (p on a Bartlett-effective n):",
        "",
        "| signal | corr | n_eff | p |",
        "|---|---|---|---|",
    ]
    for k in sorted(corr, key=lambda k: -abs(corr[k]["corr"])):
        L.append(f"| {k} | {corr[k]['corr']:+.3f} | {corr[k]['n_eff']:.0f} | {corr[k]['p_value']:.2g} |")
    L += [
        "",
        "## Candidate effects (ranked by score-test evidence)",
        "",
        f"| effect | partial R2 | p | fitted | held-out RMSE ({u}) | gain | dBIC | decision | parameters |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    num = lambda v, f: "n/a" if v is None or not np.isfinite(v) else format(v, f)  # no score test: n/a, not nan
    for c in res["candidates"]:
        ev = c["evidence"]
        head = f"| {c['name']} | {num(ev['partial_r2'], '.3f')} | {num(ev['p_value'], '.2g')} |"
        decision = c.get("decision", c.get("accepted", ""))
        if c.get("fitted"):
            par = ", ".join(f"{k}={v:.4g}" if isinstance(v, (int, float)) else f"{k}={v}" for k, v in c["parameters"].items())
            L.append(
                f"{head} yes | {c['heldout_rmse']:.4g} | {100 * c['heldout_gain']:.1f} % | "
                f"{c['delta_bic']:.1f} | {decision} | {par} |"
            )
        else:
            L.append(f"{head} no | | | | {decision} | |")
    sel = res.get("selection", {})
    if sel.get("rule") == "calibrated":
        L += ["", f"Selection rule: {sel['description']}; false-positive rate {sel['false_positive_rate']:g} ({sel['note']})."]
        for c in res["candidates"]:
            cal = c.get("calibration", {})
            if "folds" in cal:
                # a fold whose held-out prediction its training leaves undetermined is marked (it counts only when
                # fewer than two determined folds remain: `folds_gate`)
                fg = ", ".join(
                    f"{100 * f['gain']:+.1f} %" + ("" if f.get("determined", True) else " (undetermined)") for f in cal["folds"]
                )
                nl = cal.get("null")
                nt = (
                    f"; null gains mean {100 * nl['mean']:.1f} %, max {100 * nl['max']:.1f} %, threshold {100 * nl['threshold']:.1f} %"
                    if nl
                    else ""
                )
                L.append(f"- {c['name']}: fold gains {fg}{nt}")
    nm = res.get("naming")
    if nm:
        named = nm["named"] or "nothing"
        L += [
            "",
            f"Naming on the whole record ({sel.get('naming', '')}): "
            + (
                f"the gates accepted {', '.join(nm['split_selected'])}; "
                if nm["split_selected"]
                else "the base held out at the noise floor, where the gates are not run; "
            )
            + f"named: **{named}**"
            + (f" (ambiguous with {', '.join(n for n in nm['ambiguous'] if n != nm['named'])})" if nm["ambiguous"] else "")
            + "."
            + (f" Not applied: {nm['reason']}." if not nm.get("applied", True) else ""),
            "",
            f"| effect | whole-record RMSE ({u}) | gain over the refitted base ({nm['base_rmse']:.4g}) |",
            "|---|---|---|",
            *[f"| {r['name']} | {r['rmse']:.4g} | {100 * r['gain']:+.1f} % |" for r in nm["ranking"]],
        ]
    for w in res.get("warnings", []):
        L += ["", f"**Warning:** {w}"]
    s = res.get("strongest_remaining_correlate")
    if s:
        L += [
            "",
            f"Strongest remaining held-out residual correlate: `{s['signal']}` (corr {s['corr']:+.3f}, p {s['p_value']:.2g}).",
        ]
    ux = res.get("unexplained")
    if ux:
        c = ux.get("correction", {})
        L += ["", f"**Unexplained:** {ux['verdict']}."]
        if "heldout_rmse_after" in c:
            terms = ", ".join(f"`{k}` {v:+.3g}" for k, v in c["largest_terms_per_sd"].items())
            L.append(
                f"The {c['label']} is fitted on the training residual only (ridge {c['ridge']:g}, {c['ridge_rule']}); "
                f"largest terms per standard deviation of the signal: {terms}. It is not part of `extended_fit.json` "
                "and did not take part in the selection (`residual_correction.png`)."
            )
    d = res.get("deployed")
    if d:
        L += [
            "",
            f"Deployed models (`base_fit.json`, `extended_fit.json`): the same structures refitted on {d['fitted_on']} "
            f"({d['n_samples']} samples; RMSE on them: base {d['base_rmse_all']:.4g}, extended {d['extended_rmse_all']:.4g}). "
            "Use them to predict new data; the held-out figures above are those of the split fits "
            "(`base_fit_train.json`, `extended_fit_train.json`).",
        ]
    L += ["", "Plots: `residuals_before.png` (base model), `residuals_after.png` (extended model), both the split fits.", ""]
    return "\n".join(L)


def write_diagnosis(out: Path, rec: Record, diagnosis: Diagnosis) -> None:
    """All outputs of ``smafl diagnose`` into folder ``out``, from `diagnose`'s `Diagnosis` of record ``rec``."""
    from ..diagnosis._diagnose import simulate_segment
    from ..effects import ExtendedModel

    res, base, ext, split = diagnosis.report, diagnosis.base, diagnosis.extended, diagnosis.split
    atomic_write_json(out / "diagnosis.json", diagnosis.to_json_dict())
    if diagnosis.deployed_extended is None:  # diagnose(refit=False): the split fits are the outputs
        save_model(out / "base_fit.json", base, **_fit_doc(rec, res, "base", split, base))
        save_model(out / "extended_fit.json", ext, **_fit_doc(rec, res, "extended", split, ext))
    else:
        # *_fit.json: refitted on the whole record, for predicting new data; *_fit_train.json: the split fits that were scored
        save_model(
            out / "base_fit.json",
            diagnosis.deployed_base,
            **_fit_doc(rec, res, "base", split, diagnosis.deployed_base, deployed=True),
        )
        save_model(
            out / "extended_fit.json",
            diagnosis.deployed_extended,
            **_fit_doc(rec, res, "extended", split, diagnosis.deployed_extended, deployed=True),
        )
        save_model(out / "base_fit_train.json", base, **_fit_doc(rec, res, "base", split, base))
        save_model(out / "extended_fit_train.json", ext, **_fit_doc(rec, res, "extended", split, ext))
    # the base (and the extended model when nothing was selected: then it is the base) runs in the (empty) effect
    # wrapper, as it was scored; an extended model and a base replacement (Preisach) run as they are
    wrap = lambda m: ExtendedModel(m, ()) if m is base else m
    ylabel = axis_label(rec.output_name, getattr(rec, "units", None))
    _plot(out / "residuals_before.png", split, lambda s: simulate_segment(wrap(base), s), f"{rec.name}: base model", ylabel)
    _plot(
        out / "residuals_after.png",
        split,
        lambda s: simulate_segment(wrap(ext), s),
        f"{rec.name}: extended ({', '.join(diagnosis.selected) or 'none'})",
        ylabel,
    )
    if diagnosis.residuals.correction is not None:
        from ..diagnosis._unexplained import plot_correction

        rlabel = ylabel.replace(ylabel.split(" (")[0], "residual", 1)
        plot_correction(
            out / "residual_correction.png", diagnosis.residuals.correction, f"{rec.name}: what is left unexplained", rlabel
        )
    atomic_write_text(out / "report.md", _report_md(rec, res))
