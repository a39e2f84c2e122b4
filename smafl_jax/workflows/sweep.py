"""A closed-loop parameter sweep as one library call (the workflow behind ``smafl sweep``).

`run_sweep` builds the loop as `run_control` does (`build_loop`), runs every
combination of two swept parameters (`smafl_jax.control._sweep.sweep`: vmap, chunked,
sharded over devices), counts the configurations whose drive leaves the range
the plant model was fitted on, ranks them by e_mean and writes, atomically, to
``out``: ``sweep.csv`` (every configuration), ``best.csv`` (the best ``top``),
``heatmap.png`` and ``metrics.json``.
"""

from __future__ import annotations

import io
import logging
import os
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from .._errors import UserInputError
from ..models._range import range_tolerance
from .control import DEFAULT_UMAX, build_loop, check_option, option_namer, prepare_out, reference_check

PathLike = str | os.PathLike

__all__ = [
    "FILES",
    "PARAMS",
    "UNITS",
    "ControlSweepResult",
    "run_sweep",
    "parse_axis",
    "sweep_range_summary",
    "sweep_reference_check",
]

LOGGER = logging.getLogger(__name__)

#: The files `run_sweep` writes to its output folder.
FILES = ("sweep.csv", "best.csv", "heatmap.png", "metrics.json")

UNITS = {
    "kp": "V/mm", "ki": "V/(mm s)", "kd": "V s/mm", "tf": "s", "umax": "V", "K": "V/(mm s)", "noise": "mm", "k1": "1/s",
    "slow_k1": "1/s", "slow_ratio": "1",
}  # fmt: skip

#: Most values on one sweep axis.
MAX_AXIS = 100_000

#: Sweepable parameter -> its path in the `ClosedLoop` PyTree.
PARAMS = {
    "kp": "pid.kp",
    "ki": "pid.ki",
    "kd": "pid.kd",
    "tf": "pid.tf",
    "umax": "pid.umax",
    "K": "compensator.K",
    "noise": "noise_sd",
    "k1": "plant.thermal.k1",
    # a plant fitted with a slow thermal mode (`JouleThermal.slow_k1`, ``slow_ratio``): how the loop fares if the slow
    # mass were slower or carried more of the heat (a thicker sleeve, another clamp)
    "slow_k1": "plant.thermal.slow_k1",
    "slow_ratio": "plant.thermal.slow_ratio",
}
#: Axes that are rates or ratios of the plant: positive, with no single-run option to check them against.
POSITIVE = ("k1", "slow_k1", "slow_ratio")

#: Least seconds between two progress lines.
PROGRESS_EVERY_S = 2.0


class ControlSweepResult(NamedTuple):
    """What `run_sweep` produced.

    ``metrics``: name -> array shaped ``(len(x values), len(y values))`` (e_mean_mm, rmse_mm,
    max_abs_error_mm, saturated_fraction, u_min_V, u_max_V); ``axes``: ``{x name: values, y name:
    values}``; ``table``: the columns of sweep.csv (one row per configuration, x-major); ``order``: the
    rows of the best ``top`` configurations, best first; ``best``: the best row; ``settings``: the loop's
    settings; ``range_check``: how many configurations drive the plant model outside its fitted range;
    ``warnings`` (text); ``out`` and ``files`` (by name).
    """

    metrics: dict[str, np.ndarray]
    axes: dict[str, np.ndarray]
    table: dict[str, np.ndarray]
    order: np.ndarray
    best: dict[str, float]
    settings: dict
    range_check: dict
    warnings: list[str]
    out: Path
    files: dict[str, Path]


def parse_axis(spec: str | tuple[str, Sequence[float]]) -> tuple[str, np.ndarray]:
    """``"name=start:stop:num"`` (linspace), ``"name=v1,v2,..."`` or ``(name, values)`` -> ``(name, values)``, checked
    against the limits of the single-run option of that name."""
    if isinstance(spec, str):
        if "=" not in spec:
            raise UserInputError(f"sweep axis {spec!r}: expected name=start:stop:num or name=v1,v2,...")
        name, vals = spec.split("=", 1)
        if name not in PARAMS:
            raise UserInputError(f"sweep axis {name!r}: choose one of {', '.join(PARAMS)}")
        try:
            if ":" in vals:
                a, b, n = vals.split(":")
                values = np.linspace(float(a), float(b), int(n))
            else:
                values = np.array([float(v) for v in vals.split(",")])
        except ValueError:
            raise UserInputError(f"sweep axis {spec!r}: cannot parse the values") from None
    else:
        try:
            name, vals = spec
            values = np.atleast_1d(np.asarray(vals, dtype=np.float64))
        except (TypeError, ValueError):
            raise UserInputError(f"sweep axis {spec!r}: expected 'name=values' or (name, values)") from None
        if name not in PARAMS:
            raise UserInputError(f"sweep axis {name!r}: choose one of {', '.join(PARAMS)}")
        if values.ndim != 1:
            raise UserInputError(f"sweep axis {name!r}: the values must be 1-D, got shape {values.shape}")
        spec = f"{name}={','.join(f'{v:g}' for v in values)}"
    if values.size < 1 or not np.all(np.isfinite(values)):
        raise UserInputError(f"sweep axis {spec!r}: need at least one finite value")
    if values.size > MAX_AXIS:
        raise UserInputError(f"sweep axis {spec!r}: {values.size} values, more than the limit of {MAX_AXIS}")
    for v in values:  # the same limits as the single-run options (`smafl control --kp ...`)
        if name in POSITIVE:
            if not v > 0:
                raise UserInputError(f"sweep axis {spec!r}: {name} values must be > 0, got {v:g}")
        else:
            try:
                check_option(name, float(v))
            except UserInputError as exc:
                raise UserInputError(f"sweep axis {spec!r}: {exc}") from None
    return name, values


def sweep_range_summary(metrics: Mapping[str, np.ndarray], settings: dict) -> dict:
    """How many configurations drive the plant model outside the input range it was fitted on, and how far."""
    rng = (settings.get("plant_fitted_ranges") or {}).get("input_range")
    if not (isinstance(rng, (list, tuple)) and len(rng) == 2):
        return {"checked": False, "note": "the plant model file carries no training input range: drive range not checked"}
    lo, hi = float(rng[0]), float(rng[1])
    u_hi, u_lo = np.asarray(metrics["u_max_V"]), np.asarray(metrics["u_min_V"])
    tol = range_tolerance(lo, hi)  # the rule of every range check (models._range): exits under 1 % of the span are noise
    out_cfg = (u_hi > hi + tol) | (u_lo < lo - tol)
    doc = {
        "checked": True,
        "fitted_range": [lo, hi],
        "tolerance": tol,
        "n_configurations": int(out_cfg.size),
        "n_outside": int(out_cfg.sum()),
        "max_above": float(max(np.max(u_hi) - hi, 0.0)),
        "max_below": float(max(lo - np.min(u_lo), 0.0)),
    }
    if doc["n_outside"]:
        doc["warning"] = (
            f"{doc['n_outside']} of {doc['n_configurations']} configurations drive the plant model outside the input range it "
            f"was fitted on [{lo:.4g}, {hi:.4g}] by more than {tol:.3g} (up to {doc['max_above']:.4g} above, {doc['max_below']:.4g} below; per "
            "configuration in sweep.csv, columns u_min_V / u_max_V): their metrics extrapolate the model"
        )
    return doc


#: An axis along which e_mean changes by less than this fraction (over every value of the other axis) is flat.
FLAT_AXIS_RTOL = 0.01
#: A median saturated fraction above this on a flat axis: the saturation is named as the likely reason.
FLAT_SATURATED = 0.5


def sweep_flat_axes(metrics: Mapping[str, np.ndarray], axes: Mapping[str, np.ndarray]) -> dict:
    """Axes along which e_mean barely changes, and whether a saturated drive explains it.

    Why: a new-user trial swept K on a loop whose drive sat at its limit; the heat map showed a flat K axis and nothing
    said that the gain could not act.  Per axis with two or more values: ``spread`` = the largest relative range of
    e_mean along it (over every value of the other axis); ``flat`` below `FLAT_AXIS_RTOL`; ``warning`` for a flat axis,
    naming the saturation when the median ``saturated_fraction`` is above `FLAT_SATURATED`."""
    e = np.asarray(metrics["e_mean_mm"], dtype=np.float64)
    sat = float(np.nanmedian(np.asarray(metrics["saturated_fraction"], dtype=np.float64)))
    doc: dict = {"rule": f"relative range of e_mean along an axis < {FLAT_AXIS_RTOL:g} at every value of the other axis"}
    for k, (name, values) in enumerate(axes.items()):
        if np.asarray(values).size < 2:
            continue
        along = np.moveaxis(e, k, -1)  # (other axis, this axis)
        ok = np.all(np.isfinite(along), axis=-1) & (np.min(np.abs(along), axis=-1) > 0)
        if not ok.any():
            continue
        spread = float(np.max(np.ptp(along[ok], axis=-1) / np.min(np.abs(along[ok]), axis=-1)))
        entry: dict = {"spread": spread, "flat": spread < FLAT_AXIS_RTOL}
        if entry["flat"]:
            why = (
                f"; the drive is saturated on a median {100 * sat:.0f} % of the samples: a loop at its drive limit cannot act on its "
                "gains (a reachable reference or a higher umax would)"
                if sat > FLAT_SATURATED
                else ""
            )
            entry["warning"] = (
                f"e_mean changes by at most {100 * spread:.2g} % along {name} (at every swept value of the other axis): "
                f"{name} has almost no effect on this loop{why}"
            )
        doc[name] = entry
    doc["median_saturated_fraction"] = sat
    return doc


def sweep_reference_check(plant, reference, settings: dict, axes: Mapping[str, np.ndarray]) -> tuple[dict, str | None]:
    """The reference against the output the plant model reaches (`reference_check`), at the largest swept ``umax``.

    A sweep whose reference the plant cannot reach ranks gains by how they saturate, not by how they track (seen in a
    new-user trial on ``smafl control``; the sweep had no such check).  Not checked when ``k1`` is swept: the reach
    differs per configuration."""
    if "k1" in axes:
        return {"checked": False, "note": "k1 is swept: the reachable output differs per configuration"}, None
    umax = float(np.max(axes["umax"])) if "umax" in axes else float(settings["u_range_V"][1])
    name = Path(str(settings["reference"])).name
    doc, warning = reference_check(plant, reference, umax, name)
    if warning and "umax" in axes:
        warning += f" (at the largest swept umax, {umax:g} V)"
        doc["warning"] = warning
    return doc, warning


#: A sweep expected to take longer than this (s) gets a note with its size and expected time (a new-user trial ran
#: 2 x 100 000 configurations for 516 s before giving up, with nothing but the progress lines to go by).
LONG_SWEEP_S = 300.0


def _duration_words(seconds: float) -> str:
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 5400:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"


def _progress_logger(every_s: float = PROGRESS_EVERY_S, size: str | None = None, shorter: str = ""):
    """``progress(done, total, elapsed)`` reporting on the ``smafl_jax.progress`` logger at most every ``every_s``
    seconds (and at the end), with an estimate of the time left.  After the second batch (the first includes the
    compilation) a sweep expected to run longer than `LONG_SWEEP_S` gets a note (``size``: its size in words;
    ``shorter``: how to make it shorter)."""
    from .._progress import LOGGER as PROGRESS

    last = [-every_s]
    batches = []

    def progress(done, total, elapsed):
        batches.append((done, elapsed))
        if len(batches) == 2 and done < total:
            (d0, t0), (d1, t1) = batches
            rate = (d1 - d0) / max(t1 - t0, 1e-9)
            expected = t1 + (total - d1) / rate
            if expected > LONG_SWEEP_S:
                LOGGER.info(
                    f"note: a long sweep: {size or f'{total} configurations'}: about {_duration_words(expected)} in all at "
                    f"the rate of the second batch ({d1 - d0} configurations in {t1 - t0:.2g} s); Ctrl-C stops it and "
                    f"writes nothing{'; ' + shorter if shorter else ''}"
                )
        if done < total and elapsed - last[0] < every_s:
            return
        last[0] = elapsed
        eta = elapsed / done * (total - done) if done else float("nan")
        PROGRESS.info(
            f"  sweep: {done}/{total} configurations, {elapsed:.0f} s elapsed"
            + (f", about {eta:.0f} s left" if done < total else "")
        )

    return progress


def _index_axis(ax, which, values, label):
    """Cells at index positions, ticks labelled with the values: any values (log-spaced, huge) plot."""
    idx = np.unique(np.linspace(0, values.size - 1, min(values.size, 8)).round().astype(int))
    getattr(ax, f"set_{which}ticks")(idx)
    getattr(ax, f"set_{which}ticklabels")([f"{values[i]:.3g}" for i in idx])
    getattr(ax, f"set_{which}label")(label)


def _heatmap_png(m, best_index, axes, title) -> bytes:
    """The log10 e_mean map as PNG bytes (a `Figure`, not pyplot: nothing global changes, nothing stays open)."""
    from matplotlib.figure import Figure

    (xn, xv), (yn, yv) = axes.items()
    fig = Figure(figsize=(7, 5))
    ax = fig.subplots()
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.log10(np.maximum(m["e_mean_mm"], 1e-12)).T
    im = ax.pcolormesh(np.arange(xv.size), np.arange(yv.size), z, shading="nearest", cmap="viridis")
    ax.plot(*np.unravel_index(best_index, m["e_mean_mm"].shape), "r*", ms=12, label="best")
    fig.colorbar(im, ax=ax, label="log10 e_mean (mm)")
    _index_axis(ax, "x", xv, f"{xn} ({UNITS[xn]})")
    _index_axis(ax, "y", yv, f"{yn} ({UNITS[yn]})")
    ax.legend()
    ax.set_title(title)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=120, bbox_inches="tight")
    return buf.getvalue()


def run_sweep(
    x: str | tuple[str, Sequence[float]],
    y: str | tuple[str, Sequence[float]],
    model: PathLike | Any | None = None,
    *,
    out: PathLike,
    top: int = 10,
    shard: bool = True,
    progress: bool | Callable[[int, int, float], None] = True,
    option_names: Mapping[str, str] | None = None,
    **loop: Any,
) -> ControlSweepResult:
    """e_mean (and the other closed-loop metrics) for every combination of the ``x`` and ``y`` axis values.

    ``x`` / ``y``: ``"kp=5:60:12"`` (linspace), ``"K=0,5,10"`` or ``("kp", values)``; sweepable: `PARAMS`.
    ``model`` and ``loop``: the settings of `build_loop` / `run_control` (plant, reference, controller,
    gains, dt, duration, ...), the base configuration.  ``top``: rows of best.csv.  ``shard``: spread the
    batch over the devices.  ``progress``: True reports on the ``smafl_jax.progress`` logger, or a callable
    ``progress(done, total, elapsed_s)``.  Every setting is checked before anything is written.
    """
    import jax

    from .._io import atomic_write_bytes, atomic_write_csv, atomic_write_json
    from ..control._sweep import sweep

    o = option_namer(option_names)
    (xn, xv), (yn, yv) = parse_axis(x), parse_axis(y)
    if xn == yn:
        raise UserInputError(f"{o('x')} and {o('y')} both sweep {xn!r}")
    controller = loop.get("controller", "composite")
    if "K" in (xn, yn) and controller != "composite":
        raise UserInputError(f"sweeping K needs {o('controller')} composite")
    if top < 1:
        raise UserInputError(f"{o('top')} must be >= 1, got {top}")
    if "umax" in (xn, yn) and loop.get("umax") is None:
        loop = {**loop, "umax": DEFAULT_UMAX}  # swept: the base value is not used, no note about it
    base, settings = build_loop(model, option_names=option_names, **loop)
    for name in {xn, yn} & set(POSITIVE):
        if not hasattr(base.plant, "thermal"):
            raise UserInputError(f"sweeping {name} needs a plant with a thermal part (a Cascade)")
        if name.startswith("slow_") and not base.plant.thermal.has_slow_mode:
            raise UserInputError(
                f"sweeping {name} needs a plant with a slow thermal mode (smafl fit --slow-mode on, or a fit that kept one)"
            )
    dt = settings["dt_s"]
    out = prepare_out(out, LOGGER)
    axes = {xn: xv, yn: yv}
    ref_check, ref_warning = sweep_reference_check(base.plant, base.reference, settings, axes)
    settings["reference_check"] = ref_check  # as `run_control` writes it: in metrics.json's settings
    if ref_warning:  # before the sweep: it may run for minutes on a reference that cannot be tracked
        LOGGER.warning(ref_warning)
    n = xv.size * yv.size
    size = f"{n} configurations ({xv.size} {xn} x {yv.size} {yn}) x {settings['n_samples']} samples"
    LOGGER.info(f"sweeping {size} on {len(jax.devices())} device(s) ...")
    shorter = f"fewer values per axis or a shorter {o('duration')} or reference take less"
    report = _progress_logger(size=size, shorter=shorter) if progress is True else (progress or None)
    try:
        res = sweep(base, dt, {PARAMS[xn]: xv, PARAMS[yn]: yv}, shard=shard, progress=report)
    except ValueError as exc:
        raise UserInputError(str(exc)) from None
    m = res.metrics
    range_check = sweep_range_summary(m, settings)
    flat = sweep_flat_axes(m, {xn: xv, yn: yv})
    warnings = [range_check["warning"]] if range_check.get("warning") else []
    warnings += [v["warning"] for v in flat.values() if isinstance(v, dict) and v.get("warning")]
    for w in warnings:
        LOGGER.warning(w)
    warnings = [ref_warning, *warnings] if ref_warning else warnings
    X, Y = np.meshgrid(xv, yv, indexing="ij")
    table = {xn: X.ravel(), yn: Y.ravel(), **{k: v.ravel() for k, v in m.items()}}
    e = np.where(np.isfinite(m["e_mean_mm"]), m["e_mean_mm"], np.inf).ravel()
    order = np.argsort(e)[:top]
    # the figure is drawn first: nothing is written when it fails
    png = _heatmap_png(m, order[0], axes, f"{controller}, reference {settings['reference']}")
    files = {name: out / name for name in FILES}
    atomic_write_csv(files["sweep.csv"], table)
    atomic_write_csv(files["best.csv"], {k: v[order] for k, v in table.items()})
    atomic_write_bytes(files["heatmap.png"], png)
    best = {k: float(v[order[0]]) for k, v in table.items()}
    atomic_write_json(
        files["metrics.json"],
        {"best": best, "n_configurations": n, "axes": axes, "settings": settings, "range_check": range_check, "flat_axes": flat},
    )
    return ControlSweepResult(dict(m), axes, table, order, best, settings, range_check, warnings, out, files)
