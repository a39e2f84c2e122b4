"""Cross-validated diagnosis of the SMA FORC record over the three interleaved branch folds (issue 6).

Run:  python experiments/diagnose_forc_cv.py [--data ../shared/data/real] [--out experiments/results/diagnose_forc_cv.json]
For each fold (branches with label % 3 == 0, 1, 2 held out; branch 0 always trained) the blind
diagnosis runs and the held-out e_r (eq. 3) of the base EUPI and of the selected model are reported,
plus fixed structures (output_saturation, input_warp, both) fitted on the same fold for comparison.
Data are read in place (source: ../shared/data/real/README.md).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

FIXED = (["output_saturation"], ["input_warp"], ["output_saturation", "input_warp"])


def main(argv=None):
    from smafl_jax import atomic_write_json, load_record
    from smafl_jax.diagnosis import diagnose, fit_extended
    from smafl_jax.diagnosis._diagnose import _metrics_pair  # private: diagnosis helper, no public equivalent

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=str(ROOT.parent / "shared" / "data" / "real"))
    ap.add_argument("--out", default=str(ROOT / "experiments" / "results" / "diagnose_forc_cv.json"))
    a = ap.parse_args(argv)
    rec = load_record(Path(a.data) / "sma_wing_forc_train.csv")
    rows = []
    for r in (0, 1, 2):
        print(f"== fold: label % 3 == {r} held out", file=sys.stderr)
        diag = diagnose(rec, holdout_residue=r, verbose=True)
        res, base, split = diag.report, diag.base, diag.split
        row = {
            "holdout_residue": r,
            "heldout_branches": split.test_labels,
            "selected": res["selected"],
            "base_heldout_e_r": res["base"]["heldout"]["e_r_percent"],
            "selected_heldout_e_r": res["extended"]["heldout"]["e_r_percent"],
            "selected_heldout_rmse": res["extended"]["heldout_rmse"],
            "parameters": res["extended"]["parameters"],
            "fixed": {},
        }
        from smafl_jax.effects import ExtendedModel

        b = ExtendedModel(base, ())
        b, _ = fit_extended(b, [], split)
        for seq in FIXED:
            m = b
            for i in range(len(seq)):  # greedy, as the selection adds effects
                m, _ = fit_extended(m, seq[: i + 1], split)
            _, te = _metrics_pair(m, split)
            row["fixed"][">".join(seq)] = {"heldout_e_r": te["e_r_percent"], "heldout_rmse": te["rmse"]}
        rows.append(row)
        print(
            f"fold {r}: selected {res['selected']} e_r {row['base_heldout_e_r']:.2f} -> {row['selected_heldout_e_r']:.2f} %; fixed "
            + ", ".join(f"{k} {v['heldout_e_r']:.2f}" for k, v in row["fixed"].items()),
            file=sys.stderr,
            flush=True,
        )
    atomic_write_json(a.out, rows)
    for row in rows:
        print(
            f"| {row['holdout_residue']} | {row['heldout_branches']} | {', '.join(row['selected']) or 'none'} | {row['base_heldout_e_r']:.2f} -> "
            f"{row['selected_heldout_e_r']:.2f} | " + " | ".join(f"{v['heldout_e_r']:.2f}" for v in row["fixed"].values()) + " |"
        )


if __name__ == "__main__":
    main()
