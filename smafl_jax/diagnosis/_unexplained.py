"""An honest "unexplained" answer for `smafl diagnose` (issue 13).

When the residual left after the selected catalogue effects (or after the base model, when none was
selected) still has structure, the diagnosis says so, names the strongest correlate and fits a
*generic*, clearly labelled correction: a ridge regression of the residual on the same candidate
signals the residual tests use (`smafl_jax.diagnosis._residuals.candidate_signals`: input level and rate,
direction, output level, elapsed time, cycle count, thermal state, extra columns), each also passed
through a causal first-order low-pass at two time constants (0.5 % and 2 % of the training duration,
at least 2 samples: a residual that lags a signal).

How (reasons):

- The regression is fitted on the TRAINING residual only and scored on the held-out part, so its
  held-out gain is an honest measure of how predictable the left-over structure is from these
  correlates; the ridge strength is chosen by cross-validation over contiguous training blocks
  (neighbouring samples of a structured residual are not independent), each block predicted from the
  blocks before it, as the held-out block is from the training part; white noise gets a strong ridge
  and a correction near zero.
- The ridge is the dimensionless one of `smafl_jax.identify.linear.solve` (relative to the
  column-scaled Gram diagonal), so one grid fits every record length and unit.
- The correction is never a catalogue effect and never touches the selection: it is computed after
  the selection, from its residuals, and reported beside it under ``diagnosis.json["unexplained"]``.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence

import numpy as np
from scipy.signal import lfilter

from .._errors import UserInputError
from ..identify.linear import solve

__all__ = [
    "LABEL",
    "lowpass",
    "expand_signals",
    "fit_correction",
    "apply_correction",
    "cv_ridge",
    "generic_correction",
    "structure_verdict",
    "describe",
    "unexplained_report",
    "plot_correction",
]

LOGGER = logging.getLogger(__name__)

LABEL = "generic residual regression (not a physical effect)"
RIDGES = tuple(10.0 ** (k / 2) for k in range(-16, 7))  # dimensionless (`identify.linear.solve`); 1e3 ~ no correction
N_FOLDS = 5
# low-pass time constants as fractions of the longest training segment's duration: well below the CV block length
# (1/5 of it), so that the CV can judge them; a slower low-pass is a trend the blocks cannot validate, and it
# extrapolated badly to the held-out part in tests (held-out RMSE doubled on a record with an extra column)
TAU_FRACTIONS = (0.005, 0.02)
NO_LOWPASS = ("elapsed_time", "cycle_count")  # monotone ramps: a low-pass only delays them


def lowpass(x: np.ndarray, dt: float, tau: float) -> np.ndarray:
    """Causal first-order low-pass ``y[k] = y[k-1] + a (x[k] - y[k-1])``, ``a = 1 - exp(-dt / tau)``, ``y[0] = x[0]``."""
    x = np.asarray(x, float)
    if x.size == 0:
        return x.copy()
    a = 1.0 - np.exp(-float(dt) / float(tau))
    y, _ = lfilter([a], [1.0, a - 1.0], x, zi=[(1.0 - a) * x[0]])
    return y


def expand_signals(signals: dict, dt: float, taus: Sequence[float]) -> dict:
    """The signals plus their low-passes at ``taus`` (named ``lp{tau}s:{name}``); time-like ramps are not filtered."""
    out = dict(signals)
    for tau in taus:
        for k, v in signals.items():
            if k not in NO_LOWPASS:
                out[f"lp{tau:.3g}s:{k}"] = lowpass(v, dt, tau)
    return out


def _check_columns(cols: dict, r: np.ndarray, part: str) -> tuple[list, np.ndarray]:
    r = np.asarray(r, float)
    if r.ndim != 1:
        raise UserInputError(f"the {part} residual must be 1-D, got shape {r.shape}")
    if r.size == 0:
        raise UserInputError(f"the {part} residual is empty: nothing to fit or score the correction on")
    if not np.all(np.isfinite(r)):
        raise UserInputError(f"the {part} residual has {int(np.sum(~np.isfinite(r)))} non-finite value(s)")
    if not cols:
        raise UserInputError(f"no candidate signals for the {part} part")
    names = list(cols)
    for k in names:
        v = np.asarray(cols[k], float)
        if v.shape != r.shape:
            raise UserInputError(f"{part} signal {k!r} has {v.size} samples, the {part} residual {r.size}")
        if not np.all(np.isfinite(v)):
            raise UserInputError(f"{part} signal {k!r} has non-finite values")
    return names, r


def _fit(A, b, ridge):
    # centred columns and target: the intercept (training mean) is not penalised
    ma, mb = A.mean(axis=0), float(b.mean())
    coef = solve(A - ma, b - mb, ridge=ridge, method="bvls").x
    return ma, mb, coef


def _predict(fit, A):
    ma, mb, coef = fit
    return mb + (A - ma) @ coef


def cv_ridge(
    A: np.ndarray, b: np.ndarray, ridges: Sequence[float] = RIDGES, n_folds: int = N_FOLDS, scheme: str = "forward"
) -> tuple[float, list]:
    """Ridge by CV over ``n_folds`` contiguous blocks of the rows (the CV minimum).

    ``scheme="forward"``: each block from the second on is predicted from the blocks before it (as the held-out
    time block is predicted from the training part: a correction that only interpolates between its neighbours
    is not credited); ``"kfold"``: each block from all the others.  Returns the chosen ridge and a table
    ``[{"ridge", "cv_mse", "cv_se"}]``.
    """
    if scheme not in ("forward", "kfold"):
        raise UserInputError(f"scheme must be 'forward' or 'kfold', got {scheme!r}")
    n = A.shape[0]
    if n < 2 * n_folds:
        raise UserInputError(f"{n} training samples: too few for {n_folds}-fold cross-validation of the correction")
    edges = np.linspace(0, n, n_folds + 1).astype(int)
    blocks = range(1, n_folds) if scheme == "forward" else range(n_folds)
    mse = np.zeros((len(ridges), len(blocks)))
    for col, j in enumerate(blocks):
        te = np.zeros(n, bool)
        te[edges[j] : edges[j + 1]] = True
        tr = np.arange(n) < edges[j] if scheme == "forward" else ~te
        for i, lam in enumerate(ridges):
            f = _fit(A[tr], b[tr], lam)
            mse[i, col] = float(np.mean((b[te] - _predict(f, A[te])) ** 2))
    mean = mse.mean(axis=1)
    se = mse.std(axis=1, ddof=1) / np.sqrt(mse.shape[1])
    # the CV minimum, ties going to the stronger ridge (forward CV is already conservative: a one-SE rule on top
    # halved the coefficient of a real extra-column term in tests, ridge 1 instead of 0.1)
    choice = max((i for i in range(len(ridges)) if mean[i] <= mean.min()), key=lambda i: ridges[i])
    table = [{"ridge": float(r), "cv_mse": float(m), "cv_se": float(s)} for r, m, s in zip(ridges, mean, se)]
    return float(ridges[choice]), table


def fit_correction(
    cols: dict, r: np.ndarray, *, ridges: Sequence[float] = RIDGES, n_folds: int = N_FOLDS, scheme: str = "forward"
) -> dict:
    """Ridge regression of the training residual ``r`` on the columns ``cols`` (name -> array), ridge by `cv_ridge`.

    Columns constant over the training part are dropped (they carry nothing a regression could learn).
    """
    names, r = _check_columns(cols, r, "training")
    keep = [k for k in names if np.ptp(np.asarray(cols[k], float)) > 0]
    if not keep:
        raise UserInputError("every candidate signal is constant over the training part")
    A = np.column_stack([np.asarray(cols[k], float) for k in keep])
    ridge, table = cv_ridge(A, r, ridges, n_folds, scheme)
    ma, mb, coef = _fit(A, r, ridge)
    return {"signals": keep, "mean": ma, "intercept": mb, "coef": coef, "ridge": ridge, "cv": table, "sd": A.std(axis=0)}


def apply_correction(corr: dict, cols: dict) -> np.ndarray:
    """The correction's prediction of the residual on columns ``cols`` (must hold every fitted signal)."""
    missing = [k for k in corr["signals"] if k not in cols]
    if missing:
        raise UserInputError(f"signals {missing} of the correction are missing")
    A = np.column_stack([np.asarray(cols[k], float) for k in corr["signals"]])
    return _predict((corr["mean"], corr["intercept"], corr["coef"]), A)


def _e_r(e, span):
    return float(np.max(np.abs(e)) / span * 100.0) if span and span > 0 else float("nan")


def generic_correction(
    cols_train: dict,
    r_train: np.ndarray,
    cols_test: dict,
    r_test: np.ndarray,
    *,
    y_span_train: float | None = None,
    y_span_test: float | None = None,
    min_gain: float = 0.05,
    ridges: Sequence[float] = RIDGES,
    n_folds: int = N_FOLDS,
    scheme: str = "forward",
) -> tuple[dict, dict]:
    """Fit on the training residual, apply to the held-out one; returns ``(summary, arrays)``.

    ``summary`` holds the label, signals, coefficients (per unit of each signal, and per standard deviation),
    the ridge and its CV table, RMSE and e_r (% of ``y_span_*``, the measured output range) before / after on
    both parts, and ``predictable`` (held-out RMSE cut by at least ``min_gain``).  ``arrays``: the residuals
    and corrections (for the figure).
    """
    names_te, r_test = _check_columns(cols_test, r_test, "held-out")
    corr = fit_correction(cols_train, r_train, ridges=ridges, n_folds=n_folds, scheme=scheme)
    r_train = np.asarray(r_train, float)
    missing = [k for k in corr["signals"] if k not in names_te]
    if missing:
        raise UserInputError(f"held-out part lacks signal(s) {missing} of the training part")
    c_tr = apply_correction(corr, cols_train)
    c_te = apply_correction(corr, cols_test)
    rms = lambda e: float(np.sqrt(np.mean(e**2)))
    before, after = rms(r_test), rms(r_test - c_te)
    gain = 1.0 - after / before if before > 0 else 0.0
    per_sd = {k: float(c * s) for k, c, s in zip(corr["signals"], corr["coef"], corr["sd"])}
    top = sorted(per_sd, key=lambda k: -abs(per_sd[k]))[:5]
    summary = {
        "label": LABEL,
        "signals": corr["signals"],
        # correction = intercept + sum(coefficient x signal)
        "coefficients": {
            "intercept": float(corr["intercept"] - corr["mean"] @ corr["coef"]),
            **{k: float(c) for k, c in zip(corr["signals"], corr["coef"])},
        },
        "largest_terms_per_sd": {k: per_sd[k] for k in top},
        "ridge": corr["ridge"],
        "ridge_rule": f"{scheme} CV over {n_folds} contiguous training blocks"
        + (" (each predicted from those before it)" if scheme == "forward" else ""),
        "cv": corr["cv"],
        "n_train": int(r_train.size),
        "n_heldout": int(r_test.size),
        "train_rmse_before": rms(r_train),
        "train_rmse_after": rms(r_train - c_tr),
        "heldout_rmse_before": before,
        "heldout_rmse_after": after,
        "heldout_gain": gain,
        "train_e_r_before": _e_r(r_train, y_span_train),
        "train_e_r_after": _e_r(r_train - c_tr, y_span_train),
        "heldout_e_r_before": _e_r(r_test, y_span_test),
        "heldout_e_r_after": _e_r(r_test - c_te, y_span_test),
        "min_gain": min_gain,
        "predictable": bool(gain >= min_gain),
    }
    arrays = {"train": r_train, "train_correction": c_tr, "heldout": r_test, "heldout_correction": c_te}
    return summary, arrays


#: A held-out RMSE within this many output-noise SDs leaves nothing large to explain, whatever the whiteness tests say.
SMALL_STRUCTURE_RATIO = 1.5


def structure_verdict(
    selected: Sequence[str],
    whiteness: dict | None,
    strongest: dict | None,
    p_threshold: float = 0.01,
    heldout_noise_ratio: float | None = None,
):
    """Is there significant structure left in the held-out residual?  ``(bool, reason)``.

    Structure: the Ljung-Box test rejects whiteness, or the strongest candidate-signal correlation has
    p < ``p_threshold`` (Bartlett-effective n), and the held-out RMSE is more than `SMALL_STRUCTURE_RATIO` output-noise
    SDs (``heldout_noise_ratio``, when known).  Why the size: on thousands of samples any misfit fails the whiteness
    test; a new-user trial got "structure left" on every record, also on fits at 1.03-1.14x the noise, which a user
    reads as physics the model lacks.
    """
    lb = (whiteness or {}).get("ljung_box") or {}
    reasons = []
    if lb and lb.get("p_value", 1.0) < p_threshold:
        reasons.append(f"held-out residual not white (Ljung-Box p {lb['p_value']:.2g})")
    if strongest and strongest.get("p_value", 1.0) < p_threshold:
        reasons.append(f"it correlates with {strongest['signal']} (corr {strongest['corr']:+.3f}, p {strongest['p_value']:.2g})")
    after = f"after {', '.join(selected)}" if selected else "no catalogue effect selected"
    if reasons and heldout_noise_ratio is not None and heldout_noise_ratio <= SMALL_STRUCTURE_RATIO:
        return False, (
            f"{after}; detectable but small: " + "; ".join(reasons) + f", but the held-out RMSE is {heldout_noise_ratio:.3g}x "
            f"the output's noise SD (<= {SMALL_STRUCTURE_RATIO:g}x): nothing large is left to explain"
        )
    if reasons:
        return True, f"{after}; " + "; ".join(reasons)
    return False, f"{after}; no significant structure left (Ljung-Box and candidate-signal correlations at p >= {p_threshold:g})"


def _segment_columns(model, segs, simulate: Callable, taus) -> dict:
    from ..models._hysteresis import thermal_of
    from ._residuals import candidate_signals

    cols: dict = {}
    for s in segs:
        yh = simulate(model, s)
        x = None
        if thermal_of(model) is not None:  # a thermal stage in front of the hysteresis: thermal signals too
            import jax.numpy as jnp

            x = np.asarray(model.hysteresis_input(jnp.asarray(s.u), jnp.asarray(s.dt)))
        sig = expand_signals(candidate_signals(s.time, s.u, yh, s.dt, x=x, extra=s.extra), s.dt, taus)
        for k, v in sig.items():
            cols.setdefault(k, []).append(np.asarray(v, float)[s.mask])
    return {k: np.concatenate(v) for k, v in cols.items() if len(v) == len(segs)}


def unexplained_report(
    model,
    split,
    res_train: np.ndarray,
    res_test: np.ndarray,
    *,
    selected: Sequence[str],
    whiteness: dict | None,
    strongest: dict | None,
    simulate: Callable,
    min_gain: float = 0.05,
    p_threshold: float = 0.01,
    scheme: str = "forward",
    heldout_noise_ratio: float | None = None,
) -> tuple[dict, dict | None]:
    """``diagnosis.json["unexplained"]`` for the selected model ``model`` fitted on ``split.train``.

    ``res_*``: its residuals on the (masked) training and held-out samples; ``simulate(model, segment)`` its
    output on a whole segment (the candidate signals and their low-passes run over whole segments, then the
    scored samples are taken).  ``heldout_noise_ratio``: its held-out RMSE over the output noise (`structure_verdict`).  Returns ``(doc, arrays)``; arrays is None when no correction could be fitted.
    """
    left, why = structure_verdict(selected, whiteness, strongest, p_threshold, heldout_noise_ratio)
    doc = {"structure_left": left, "why": why, "strongest_correlate": strongest}
    dur = max(float(s.time[-1] - s.time[0]) for s in split.train)
    dt = min(float(s.dt) for s in split.train)
    taus = sorted({max(f * dur, 2.0 * dt) for f in TAU_FRACTIONS})
    try:
        cols_tr = _segment_columns(model, split.train, simulate, taus)
        cols_te = _segment_columns(model, split.test, simulate, taus)
        # a signal constant on some segment (an extra column, say) is left out there: keep those on both parts
        common = [k for k in cols_tr if k in cols_te]
        cols_tr, cols_te = {k: cols_tr[k] for k in common}, {k: cols_te[k] for k in common}
        span = lambda segs: float(np.ptp(np.concatenate([s.y[s.mask] for s in segs])))
        corr, arrays = generic_correction(
            cols_tr,
            res_train,
            cols_te,
            res_test,
            y_span_train=span(split.train),
            y_span_test=span(split.test),
            min_gain=min_gain,
            scheme=scheme,
        )
    except UserInputError as err:  # e.g. a training part too short to cross-validate: say so, do not fail the diagnosis
        LOGGER.warning("generic residual correction skipped: %s", err)
        doc["correction"] = {"label": LABEL, "skipped": str(err)}
        doc["verdict"] = why + f"; generic correction skipped ({err})"
        return doc, None
    corr["lowpass_time_constants_s"] = taus
    doc["correction"] = corr
    doc["verdict"] = describe(left, corr)
    return doc, arrays


def describe(structure_left: bool, corr: dict) -> str:
    """One line: is structure left, and does the generic correction (a `generic_correction` summary) predict it?"""
    change = (
        f"held-out RMSE {corr['heldout_rmse_before']:.4g} -> {corr['heldout_rmse_after']:.4g} "
        f"({-100 * corr['heldout_gain']:+.1f} %), e_r {corr['heldout_e_r_before']:.2f} % -> {corr['heldout_e_r_after']:.2f} %"
    )
    if not structure_left:
        return f"no significant structure left; {LABEL}: {change}"
    if corr["predictable"]:
        return f"structure left that no catalogue effect explains; {LABEL}: {change}"
    return f"structure left, not predictable from these correlates ({LABEL}: {change})"


def plot_correction(path, arrays: dict, title: str, ylabel: str = "residual") -> None:
    """Training residual with the fitted correction; held-out residual without and with it (atomic write)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .._io import atomic_savefig

    fig, ax = plt.subplots(2, 1, figsize=(10, 6), layout="constrained")
    n_tr = arrays["train"].size
    x_tr, x_te = np.arange(n_tr), n_tr + np.arange(arrays["heldout"].size)
    ax[0].plot(x_tr, arrays["train"], color="0.5", lw=0.7, label="training residual")
    ax[0].plot(x_tr, arrays["train_correction"], color="C0", lw=1.0, label="fitted correction")
    ax[0].plot(x_te, arrays["heldout"], color="0.75", lw=0.7, label="held-out residual")
    ax[0].plot(x_te, arrays["heldout_correction"], color="C3", lw=1.0, label="correction (prediction)")
    ax[0].set_ylabel(ylabel)
    ax[0].legend(loc="upper right", fontsize=8)
    rms = lambda e: np.sqrt(np.mean(e**2))
    before, after = arrays["heldout"], arrays["heldout"] - arrays["heldout_correction"]
    ax[1].plot(x_te, before, color="0.5", lw=0.7, label=f"without correction (RMSE {rms(before):.3g})")
    ax[1].plot(x_te, after, color="C3", lw=0.7, label=f"with correction (RMSE {rms(after):.3g})")
    ax[1].set_ylabel(f"held-out {ylabel}")
    ax[1].set_xlabel("sample (train, then held-out)")
    ax[1].legend(loc="upper right", fontsize=8)
    fig.suptitle(f"{title}\n{LABEL}, fitted on the training residual only", fontsize=10)
    atomic_savefig(fig, path)
    plt.close(fig)
