"""``smafl sweep``: e_mean map of the closed loop over two controller / plant parameters (vmap, sharded)."""

from __future__ import annotations

import sys

import numpy as np

from .._errors import UserInputError
from .control import add_loop_arguments, build_loop, check_option

UNITS = {"kp": "V/mm", "ki": "V/(mm s)", "kd": "V s/mm", "tf": "s", "umax": "V", "K": "V/(mm s)", "noise": "mm", "k1": "1/s"}

#: Most values on one sweep axis.
MAX_AXIS = 100_000

# CLI name -> path in the ClosedLoop PyTree
PARAMS = {
    "kp": "pid.kp",
    "ki": "pid.ki",
    "kd": "pid.kd",
    "tf": "pid.tf",
    "umax": "pid.umax",
    "K": "compensator.K",
    "noise": "noise_sd",
    "k1": "plant.thermal.k1",
}


def parse_axis(spec):
    """``name=start:stop:num`` (linspace) or ``name=v1,v2,...`` -> (name, values)."""
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
    if values.size < 1 or not np.all(np.isfinite(values)):
        raise UserInputError(f"sweep axis {spec!r}: need at least one finite value")
    if values.size > MAX_AXIS:
        raise UserInputError(f"sweep axis {spec!r}: {values.size} values, more than the limit of {MAX_AXIS}")
    for v in values:  # the same limits as the single-run options (`smafl control --kp ...`)
        if name == "k1":
            if not v > 0:
                raise UserInputError(f"sweep axis {spec!r}: k1 values must be > 0, got {v:g}")
        else:
            try:
                check_option(name, float(v))
            except UserInputError as exc:
                raise UserInputError(f"sweep axis {spec!r}: {str(exc).replace('--' + name, name)}") from None
    return name, values


def _index_axis(ax, which, values, label):
    """Cells at index positions, ticks labelled with the values: any values (log-spaced, huge) plot."""
    idx = np.unique(np.linspace(0, values.size - 1, min(values.size, 8)).round().astype(int))
    getattr(ax, f"set_{which}ticks")(idx)
    getattr(ax, f"set_{which}ticklabels")([f"{values[i]:.3g}" for i in idx])
    getattr(ax, f"set_{which}label")(label)


def _progress_printer(n, stream=None, every_s=2.0):
    """``progress(done, total, elapsed)`` callback printing at most every ``every_s`` seconds, with an estimate."""
    last = [-every_s]

    def progress(done, total, elapsed):
        if done < total and elapsed - last[0] < every_s:
            return
        last[0] = elapsed
        eta = elapsed / done * (total - done) if done else float("nan")
        print(
            f"  sweep: {done}/{total} configurations, {elapsed:.0f} s elapsed"
            + (f", about {eta:.0f} s left" if done < total else ""),
            file=stream or sys.stderr,
            flush=True,
        )

    return progress


def sweep_range_summary(metrics, settings) -> dict:
    """How many configurations drive the plant model outside the input range it was fitted on, and how far."""
    rng = (settings.get("plant_fitted_ranges") or {}).get("input_range")
    if not (isinstance(rng, (list, tuple)) and len(rng) == 2):
        return {"checked": False, "note": "the plant model file carries no training input range: drive range not checked"}
    lo, hi = float(rng[0]), float(rng[1])
    u_hi, u_lo = np.asarray(metrics["u_max_V"]), np.asarray(metrics["u_min_V"])
    out_cfg = (u_hi > hi) | (u_lo < lo)
    doc = {
        "checked": True,
        "fitted_range": [lo, hi],
        "n_configurations": int(out_cfg.size),
        "n_outside": int(out_cfg.sum()),
        "max_above": float(max(np.max(u_hi) - hi, 0.0)),
        "max_below": float(max(lo - np.min(u_lo), 0.0)),
    }
    if doc["n_outside"]:
        doc["warning"] = (
            f"{doc['n_outside']} of {doc['n_configurations']} configurations drive the plant model outside the input range it "
            f"was fitted on [{lo:.4g}, {hi:.4g}] (up to {doc['max_above']:.4g} above, {doc['max_below']:.4g} below; per "
            "configuration in sweep.csv, columns u_min_V / u_max_V): their metrics extrapolate the model"
        )
    return doc


def add_parser(sub):
    p = sub.add_parser("sweep", help="heat map of closed-loop e_mean over two swept parameters")
    add_loop_arguments(p)
    p.add_argument("--x", required=True, help=f"first axis, e.g. kp=5:60:12 (names: {', '.join(PARAMS)})")
    p.add_argument("--y", required=True, help="second axis, e.g. K=0:20:11")
    p.add_argument("--top", type=int, default=10, help="rows of the best-settings table")
    p.add_argument("--no-shard", action="store_true", help="do not shard the batch over devices")
    p.add_argument("--out", required=True, help="output folder (heatmap.png, sweep.csv, best.csv, metrics.json)")
    p.set_defaults(func=run)
    return p


def run(args):
    import jax
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .._io import atomic_write_bytes, atomic_write_csv, atomic_write_json, prepare_out_dir
    from .._sweep import sweep

    (xn, xv), (yn, yv) = parse_axis(args.x), parse_axis(args.y)
    if xn == yn:
        raise UserInputError(f"--x and --y both sweep {xn!r}")
    if "K" in (xn, yn) and args.controller != "composite":
        raise UserInputError("sweeping K needs --controller composite")
    if args.top < 1:
        raise UserInputError(f"--top must be >= 1, got {args.top}")
    loop, settings = build_loop(args)
    if "k1" in (xn, yn) and not hasattr(loop.plant, "thermal"):
        raise UserInputError("sweeping k1 needs a plant with a thermal part (a Cascade)")
    out = prepare_out_dir(args.out)
    n = xv.size * yv.size
    print(f"sweeping {n} configurations x {settings['n_samples']} samples on {len(jax.devices())} device(s) ...", file=sys.stderr)
    try:
        res = sweep(loop, args.dt, {PARAMS[xn]: xv, PARAMS[yn]: yv}, shard=not args.no_shard, progress=_progress_printer(n))
    except ValueError as exc:
        raise UserInputError(str(exc)) from None
    m = res.metrics
    range_summary = sweep_range_summary(m, settings)
    if range_summary.get("warning"):
        print(f"warning: {range_summary['warning']}", file=sys.stderr)
    X, Y = np.meshgrid(xv, yv, indexing="ij")
    cols = {xn: X.ravel(), yn: Y.ravel(), **{k: v.ravel() for k, v in m.items()}}
    e = np.where(np.isfinite(m["e_mean_mm"]), m["e_mean_mm"], np.inf).ravel()
    order = np.argsort(e)[: args.top]
    # the figure is drawn first: nothing is written when it fails
    fig, ax = plt.subplots(figsize=(7, 5))
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.log10(np.maximum(m["e_mean_mm"], 1e-12)).T
    im = ax.pcolormesh(np.arange(xv.size), np.arange(yv.size), z, shading="nearest", cmap="viridis")
    ax.plot(*np.unravel_index(order[0], m["e_mean_mm"].shape), "r*", ms=12, label="best")
    fig.colorbar(im, ax=ax, label="log10 e_mean (mm)")
    _index_axis(ax, "x", xv, f"{xn} ({UNITS[xn]})")
    _index_axis(ax, "y", yv, f"{yn} ({UNITS[yn]})")
    ax.legend()
    ax.set_title(f"{args.controller}, reference {settings['reference']}")
    import io

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=120, bbox_inches="tight")
    plt.close(fig)
    atomic_write_csv(out / "sweep.csv", cols)
    atomic_write_csv(out / "best.csv", {k: v[order] for k, v in cols.items()})
    atomic_write_bytes(out / "heatmap.png", buf.getvalue())
    best = {k: float(v[order[0]]) for k, v in cols.items()}
    atomic_write_json(
        out / "metrics.json",
        {"best": best, "n_configurations": n, "axes": {xn: xv, yn: yv}, "settings": settings, "range_check": range_summary},
    )
    print(f"{'rank':>4} {xn:>10} {yn:>10} {'e_mean_mm':>12} {'rmse_mm':>10} {'saturated':>9}")
    for i, j in enumerate(order):
        print(
            f"{i + 1:>4} {cols[xn][j]:>10.4g} {cols[yn][j]:>10.4g} {cols['e_mean_mm'][j]:>12.4g} {cols['rmse_mm'][j]:>10.4g} {cols['saturated_fraction'][j]:>9.3f}"
        )
    print(f"-> {out}")
    return 0
