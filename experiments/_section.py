"""Shared runner for the per-figure scripts: one section of `smafl paper` on the bundled records."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import smafl_jax as sj
from smafl_jax import paper as _paper
from smafl_jax import to_jsonable

ROOT = Path(__file__).resolve().parents[1]


def run_section(name, section, doc, argv=None):
    """Parse ``--out``/``--quick``, run ``_paper.<section>`` and print its numbers as JSON."""
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    ap.add_argument("--out", default=str(ROOT / "experiments" / "out" / name))
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args(argv)
    out = sj.prepare_out_dir(args.out)
    recs = {n: sj.load_record(ROOT / "datasets" / f"{n}.csv") for n in ("main_loop", "minor_loop", "steps")}
    res = getattr(_paper, section)(recs, out, args.quick)
    print(json.dumps(to_jsonable({k: v for k, v in res.items() if k != "figures"}), indent=2, default=str))
    print("figures:", ", ".join(str(f) for f in res["figures"]))
    return 0
