"""Figures of the uncertainty report: corner, trace and posterior-predictive plots (matplotlib, Agg)."""

from __future__ import annotations

import numpy as np

__all__ = [
    "corner_figure",
    "trace_figure",
    "predictive_time_figure",
    "predictive_loop_figure",
    "panels_figure",
    "parameter_label",
]

#: Units of the parameters the sampler can draw (the rest are in the model's own units, said as such).
PARAMETER_UNITS = {
    "thermal.k1": "1/s",
    "time_constant_s": "s",
    "thermal.u0": "V",
    "offset": "output units",
    "noise.sigma": "output units",
    "noise.nu": "unitless",
}


def parameter_label(name, output_unit=None):
    """``thermal.k1 (1/s)``; the noise scale and offsets in the output's unit when known."""
    unit = PARAMETER_UNITS.get(name)
    if unit == "output units" and output_unit:
        unit = output_unit
    return f"{name} ({unit or 'model units'})"


def _with_unit(label):
    """An axis label that already names its unit stays; a bare column name gets one (or says it has none)."""
    from ._reportdoc import axis_label

    return label if "(" in str(label) else axis_label(label)


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def corner_figure(samples, names, truths=None, max_params=8, bins=40, output_unit=None):
    """Pairwise 2-D histograms below the diagonal, marginals on it (first ``max_params`` parameters)."""
    plt = _plt()
    samples = np.asarray(samples)[:, :max_params]
    names = [parameter_label(n, output_unit) for n in list(names)[:max_params]]
    d = samples.shape[1]
    fig, axes = plt.subplots(d, d, figsize=(1.9 * d + 1, 1.9 * d + 1), squeeze=False)
    lims = [np.quantile(samples[:, j], [0.001, 0.999]) for j in range(d)]
    for i in range(d):
        for j in range(d):
            ax = axes[i, j]
            if j > i:
                ax.axis("off")
                continue
            if i == j:
                ax.hist(samples[:, j], bins=bins, range=tuple(lims[j]), color="0.3", histtype="step")
                q = np.quantile(samples[:, j], [0.025, 0.5, 0.975])
                for v in q:
                    ax.axvline(v, color="C0", ls="--", lw=0.8)
                ax.set_yticks([])
                ax.set_title(f"{names[j]}\n{q[1]:.4g} [{q[0]:.4g}, {q[2]:.4g}]", fontsize=7)
            else:
                ax.hist2d(samples[:, j], samples[:, i], bins=bins, range=[lims[j], lims[i]], cmap="Greys")
            if truths is not None and truths[j] is not None:
                ax.axvline(truths[j], color="C3", lw=0.8)
                if i != j and truths[i] is not None:
                    ax.axhline(truths[i], color="C3", lw=0.8)
            ax.tick_params(labelsize=6)
            if i < d - 1:
                ax.set_xticklabels([])
            else:
                ax.set_xlabel(names[j], fontsize=7)
            if j > 0 or i == 0:
                if i != j:
                    ax.set_yticklabels([])
            else:
                ax.set_ylabel(names[i], fontsize=7)
    fig.suptitle("posterior (physical units); dashed: 2.5 / 50 / 97.5 %; density axes unlabelled (relative)", fontsize=9)
    return fig


def trace_figure(chain_phys, names, burn, max_params=8, max_walkers=16, output_unit=None):
    """Walker traces per parameter; the grey band is the discarded burn-in."""
    plt = _plt()
    names = [parameter_label(n, output_unit) for n in names]
    chain_phys = np.asarray(chain_phys)
    d = min(chain_phys.shape[2], max_params)
    fig, axes = plt.subplots(d, 1, figsize=(8, 1.4 * d + 0.6), sharex=True, squeeze=False)
    steps = np.arange(chain_phys.shape[0])
    for j in range(d):
        ax = axes[j, 0]
        ax.plot(steps, chain_phys[:, :max_walkers, j], lw=0.4, alpha=0.6)
        ax.axvspan(0, burn, color="0.85", zorder=-1)
        ax.set_ylabel(names[j], fontsize=7)
        ax.tick_params(labelsize=6)
    axes[-1, 0].set_xlabel("sampler step (count)")
    fig.suptitle(f"traces ({min(max_walkers, chain_phys.shape[1])} of {chain_phys.shape[1]} walkers); grey: burn-in", fontsize=9)
    return fig


def predictive_time_figure(time, y, f, yrep, train_mask, *, ylabel="output", ax=None, title=None):
    """95 % bands of the mean function and of new observations over time, data on top: ``(figure, held-out coverage)``.

    ``ax``: draw into this axes (one panel per record of a joint posterior); ``title``: what the panel shows."""
    fq = np.quantile(f, [0.025, 0.5, 0.975], axis=0)
    yq = np.quantile(yrep, [0.025, 0.975], axis=0)
    if ax is None:
        fig, ax = _plt().subplots(figsize=(9, 3.6))
    else:
        fig = ax.figure
    ax.fill_between(time, yq[0], yq[1], color="C0", alpha=0.2, lw=0, label="95 % predictive (with noise)")
    ax.fill_between(time, fq[0], fq[1], color="C0", alpha=0.5, lw=0, label="95 % model (mean function)")
    ax.plot(time, fq[1], color="C0", lw=0.8, label="posterior median")
    tm = np.asarray(train_mask, bool)
    ax.plot(time[tm], y[tm], ".", ms=1.5, color="0.4", label="data used for sampling")
    if (~tm).any():
        ax.plot(time[~tm], y[~tm], ".", ms=2, color="C3", label="held-out data")
    ax.set_xlabel("time (s)")
    ax.set_ylabel(_with_unit(ylabel))
    ax.legend(fontsize=7, loc="best")
    cover = float(np.mean((y[~tm] >= yq[0][~tm]) & (y[~tm] <= yq[1][~tm]))) if (~tm).any() else None
    ttl = title or "posterior predictive over time"
    if cover is not None:
        ttl += f"; held-out points inside the 95 % predictive band: {100 * cover:.1f} %"
    ax.set_title(ttl, fontsize=9)
    return fig, cover


def predictive_loop_figure(u, y, f, train_mask, *, xlabel="input", ylabel="output", n_draws=30, ax=None, title=None):
    """Hysteresis loop: posterior draws of the model output against the input, data on top (``ax``, ``title``: as
    `predictive_time_figure`)."""
    if ax is None:
        fig, ax = _plt().subplots(figsize=(5.5, 4.5))
    else:
        fig = ax.figure
    for k in range(min(n_draws, f.shape[0])):
        ax.plot(u, f[k], color="C0", lw=0.4, alpha=0.25, label="posterior draws" if k == 0 else None)
    fq = np.quantile(f, [0.025, 0.975], axis=0)
    ax.plot(u, fq[0], color="C0", lw=0.6, ls="--", label="2.5 / 97.5 % (pointwise)")
    ax.plot(u, fq[1], color="C0", lw=0.6, ls="--")
    tm = np.asarray(train_mask, bool)
    ax.plot(u[tm], y[tm], ".", ms=1.5, color="0.4", label="data used for sampling")
    if (~tm).any():
        ax.plot(u[~tm], y[~tm], ".", ms=2, color="C3", label="held-out data")
    ax.set_xlabel(_with_unit(xlabel))
    ax.set_ylabel(_with_unit(ylabel))
    ax.legend(fontsize=7)
    ax.set_title(title or "posterior predictive over the hysteresis loop", fontsize=9)
    return fig


def panels_figure(n: int, *, width: float, height: float, columns: int = 1):
    """``(figure, flat list of n axes)``: one panel per record of a joint posterior (spare panels hidden)."""
    rows = -(-n // columns)
    fig, axes = _plt().subplots(rows, columns, figsize=(width * columns, height * rows), squeeze=False)
    flat = list(axes.ravel())
    for ax in flat[n:]:
        ax.set_visible(False)
    fig.set_layout_engine("constrained")
    return fig, flat[:n]
