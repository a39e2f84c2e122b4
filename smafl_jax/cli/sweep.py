"""``smafl sweep``: e_mean map of the closed loop over two controller / plant parameters (vmap, sharded)."""

from __future__ import annotations

import sys

import numpy as np

from .._errors import UserInputError
from .control import add_loop_arguments, build_loop

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
    return name, values


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

    from .._io import atomic_savefig, atomic_write_csv, atomic_write_json, prepare_out_dir
    from .._sweep import sweep

    (xn, xv), (yn, yv) = parse_axis(args.x), parse_axis(args.y)
    if xn == yn:
        raise UserInputError(f"--x and --y both sweep {xn!r}")
    if "K" in (xn, yn) and args.controller != "composite":
        raise UserInputError("sweeping K needs --controller composite")
    if "k1" in (xn, yn) and np.any(np.concatenate([xv, yv]) <= 0):
        raise UserInputError("k1 values must be > 0")
    loop, settings = build_loop(args)
    if "k1" in (xn, yn) and not hasattr(loop.plant, "thermal"):
        raise UserInputError("sweeping k1 needs a plant with a thermal part (a Cascade)")
    out = prepare_out_dir(args.out)
    n = xv.size * yv.size
    print(f"sweeping {n} configurations x {settings['n_samples']} samples on {len(jax.devices())} device(s) ...", file=sys.stderr)
    try:
        res = sweep(loop, args.dt, {PARAMS[xn]: xv, PARAMS[yn]: yv}, shard=not args.no_shard)
    except ValueError as exc:
        raise UserInputError(str(exc)) from None
    m = res.metrics
    X, Y = np.meshgrid(xv, yv, indexing="ij")
    cols = {xn: X.ravel(), yn: Y.ravel(), **{k: v.ravel() for k, v in m.items()}}
    atomic_write_csv(out / "sweep.csv", cols)
    e = np.where(np.isfinite(m["e_mean_mm"]), m["e_mean_mm"], np.inf).ravel()
    order = np.argsort(e)[: max(1, args.top)]
    atomic_write_csv(out / "best.csv", {k: v[order] for k, v in cols.items()})
    fig, ax = plt.subplots(figsize=(7, 5))
    im = ax.pcolormesh(xv, yv, np.log10(np.maximum(m["e_mean_mm"], 1e-12)).T, shading="nearest", cmap="viridis")
    ax.plot(cols[xn][order[0]], cols[yn][order[0]], "r*", ms=12, label="best")
    fig.colorbar(im, ax=ax, label="log10 e_mean (mm)")
    ax.set_xlabel(xn)
    ax.set_ylabel(yn)
    ax.legend()
    ax.set_title(f"{args.controller}, reference {settings['reference']}")
    atomic_savefig(fig, out / "heatmap.png")
    plt.close(fig)
    best = {k: float(v[order[0]]) for k, v in cols.items()}
    atomic_write_json(out / "metrics.json", {"best": best, "n_configurations": n, "axes": {xn: xv, yn: yv}, "settings": settings})
    print(f"{'rank':>4} {xn:>10} {yn:>10} {'e_mean_mm':>12} {'rmse_mm':>10} {'saturated':>9}")
    for i, j in enumerate(order):
        print(
            f"{i + 1:>4} {cols[xn][j]:>10.4g} {cols[yn][j]:>10.4g} {cols['e_mean_mm'][j]:>12.4g} {cols['rmse_mm'][j]:>10.4g} {cols['saturated_fraction'][j]:>9.3f}"
        )
    print(f"-> {out}")
    return 0
