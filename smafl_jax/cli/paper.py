"""``smafl paper [--out DIR] [--quick]``: the end-to-end reproduction report on the bundled records."""

from __future__ import annotations


def add_parser(sub):
    p = sub.add_parser("paper", help="reproduce the paper end to end on the bundled data and write one report")
    p.add_argument("--out", default="out/paper", help="output folder (default: out/paper)")
    p.add_argument(
        "--quick",
        action="store_true",
        help="fewer solver steps and samples, skips the slow-sine control case and two diagnoses (< 2 min on 2 cores)",
    )
    p.add_argument("--datasets", default=None, help="folder of bundled records (default: the repository's datasets/)")
    p.add_argument(
        "--real-data", default=None, help="folder of real measured records (default: ../shared/data/real beside the repo)"
    )
    p.add_argument("--seed", type=int, default=0, help="seed for the sampler and anything random")
    p.set_defaults(func=run)
    return p


def run(args):
    import sys
    from pathlib import Path

    from ..paper._paper import run_paper

    s = run_paper(args.out, quick=args.quick, datasets=args.datasets, real=args.real_data, seed=args.seed)
    out = Path(s["out"])
    print(f"wrote {out / 'report.md'}, {out / 'report.html'} and {out / 'paper.json'} ({s['elapsed_s']:.0f} s)", file=sys.stderr)
    return 0
