"""Issue 18: which cells of the independent-plant matrix hold out an untrained branch of the plant's own state.

For each record of `base_fit_before_after.py`'s matrix (tests/indep_plant.py, no smafl_jax inside the plant) the
plant's true hysteresis input (its thermal state x_h, from the simulator's own trace) is checked with
`smafl_jax.data.branch_coverage`: the fraction of held-out samples (last 30 %) whose x_h value the training part
visits on the same branch (rising / falling, deadband 2 % of the span).  The cell's held-out RMSE / noise is read
from a results file of base_fit_before_after.py, so the table says whether the misses are predictions or
extrapolations to a branch the fit never saw.

Run:  python experiments/matrix_branch_coverage.py experiments/results/base_fit_matrix_session16_prior.json 10
"""

import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
import indep_plant as ip  # noqa: E402

from smafl_jax.data import branch_coverage  # noqa: E402

CELLS = dict(ip.MATRIX_CELLS)


def main(path, minutes):
    rows = json.loads(Path(path).read_text())
    print("| cell | seed | held-out / noise | coverage of x_h (true state) | falling held-out covered | rising covered |")
    print("| --- | --- | --- | --- | --- | --- |")
    good, bad = [], []
    for r in rows:
        rec = ip.make_record(r["seed"], minutes=minutes, **CELLS[r["cell"]])
        x = np.asarray(rec["sim"]["x_h"], float)
        train = np.arange(x.size) < rec["heldout_start"]
        cov = branch_coverage(x, train, ~train, what="plant thermal state")
        bd = cov["by_direction"]
        f = bd.get("falling", {}).get("covered")
        u = bd.get("rising", {}).get("covered")
        print(
            f"| {r['cell']} | {r['seed']} | {r['held']:.2f} | {100 * cov['covered_fraction']:.0f} % | "
            f"{'-' if f is None else f'{100 * f:.0f} %'} | {'-' if u is None else f'{100 * u:.0f} %'} |"
        )
        (good if cov["covered_fraction"] >= 0.9 else bad).append(r["held"])
    for name, h in (("covered >= 90 %", good), ("covered < 90 %", bad)):
        h = np.asarray(h)
        if h.size:
            print(
                f"\n- {name}: {h.size} cells, median held-out {np.median(h):.2f}x noise, within 1.5x {int(np.sum(h <= 1.5))}, "
                f"within 3x {int(np.sum(h <= 3))}"
            )


if __name__ == "__main__":
    main(sys.argv[1], float(sys.argv[2]) if len(sys.argv) > 2 else 10.0)
