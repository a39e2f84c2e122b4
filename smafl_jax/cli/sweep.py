"""``smafl sweep``: e_mean map of the closed loop over two controller / plant parameters (vmap, sharded).

The workflow is `smafl_jax.workflows.sweep.run_sweep`; this module parses the arguments, shows the
workflow's progress, notes and warnings on stderr and prints the best settings.
"""

from __future__ import annotations

from .control import OPTION_NAMES, add_loop_arguments, loop_options, workflow_lines_on_stderr


def add_parser(sub):
    from ..workflows.sweep import PARAMS  # numpy only: the help stays fast

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
    from ..workflows.sweep import run_sweep

    with workflow_lines_on_stderr():
        res = run_sweep(
            args.x, args.y, out=args.out, top=args.top, shard=not args.no_shard, option_names=OPTION_NAMES, **loop_options(args)
        )
    xn, yn = res.axes
    cols = res.table
    print(f"{'rank':>4} {xn:>10} {yn:>10} {'e_mean_mm':>12} {'rmse_mm':>10} {'saturated':>9}")
    for i, j in enumerate(res.order):
        print(
            f"{i + 1:>4} {cols[xn][j]:>10.4g} {cols[yn][j]:>10.4g} {cols['e_mean_mm'][j]:>12.4g} {cols['rmse_mm'][j]:>10.4g} "
            f"{cols['saturated_fraction'][j]:>9.3f}"
        )
    print(f"-> {res.out}")
    return 0
