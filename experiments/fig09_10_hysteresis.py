"""Paper figs. 9-10: EUPI hysteresis loops (main and minor loop) and the e_r of eq. (3) vs the paper's 6.3 %.

    python experiments/fig09_10_hysteresis.py [--out experiments/out/fig09_10_hysteresis] [--quick]

Runs the same code as the corresponding section of `smafl paper` on the bundled
records and prints the numbers; figures and the fitted model go to --out.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import smafl_jax as sj
from smafl_jax import _paper
from smafl_jax._io import to_jsonable

ROOT = Path(__file__).resolve().parents[1]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(ROOT / "experiments" / "out" / "fig09_10_hysteresis"))
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args(argv)
    out = sj.prepare_out_dir(args.out)
    recs = {n: sj.load_record(ROOT / "datasets" / f"{n}.csv") for n in ("main_loop", "minor_loop", "steps")}
    res = _paper.section_eupi(recs, out, args.quick)
    shown = {k: v for k, v in res.items() if k not in ("figures",)}
    print(json.dumps(to_jsonable(shown), indent=2, default=str))
    print("figures:", ", ".join(str(f) for f in res["figures"]))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
