"""Diagnosis of the real records (issue 6): SMA wing FORC data and NiTi water-step records.

Run:  python experiments/diagnose_real.py [--data ../shared/data/real] [--out experiments/results/diagnose_real] [--only water_step]
Writes one `smafl diagnose` output folder per record and summary.json / summary.md.
Data are read in place (never copied); sources are cited in ../shared/data/real/README.md.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

RECORDS = [
    ("sma_wing_forc_train.csv", None, None),
    *[(f"niti_wire_water_step_0{i}.csv", "temperature_front_C", "length_signal") for i in range(1, 5)],
]


def main(argv=None):
    from smafl_jax import atomic_write_json, atomic_write_text, load_record, prepare_out_dir
    from smafl_jax.diagnosis import diagnose
    from smafl_jax.report import write_diagnosis

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=str(ROOT.parent / "shared" / "data" / "real"))
    ap.add_argument("--out", default=str(ROOT / "experiments" / "results" / "diagnose_real"))
    ap.add_argument("--only", default=None, help="run only the records whose file name contains this text")
    a = ap.parse_args(argv)
    out = prepare_out_dir(a.out)
    rows = []
    for name, inp, outp in RECORDS:
        if a.only and a.only not in name:
            continue
        path = Path(a.data) / name
        if not path.exists():
            print(f"skip {name}: not found under {a.data}", file=sys.stderr)
            continue
        rec = load_record(path, input=inp, output=outp)
        print(f"== {name}", file=sys.stderr)
        diag = diagnose(rec, verbose=True)
        res = diag.report
        d = out / path.stem
        d.mkdir(exist_ok=True)
        write_diagnosis(d, rec, diag)
        rows.append(
            {
                "record": name,
                "base": res["base"]["rule"],
                "split": res["split"]["rule"],
                "selected": res["selected"],
                "evidence_top": res["evidence_ranking"][:3],
                "heldout_rmse_before": res["base"]["heldout_rmse"],
                "heldout_rmse_after": res["extended"]["heldout_rmse"],
                "heldout_e_r_before": res["base"]["heldout"]["e_r_percent"],
                "heldout_e_r_after": res["extended"]["heldout"]["e_r_percent"],
                "parameters": res["extended"]["parameters"],
                "strongest_remaining_correlate": res["strongest_remaining_correlate"],
            }
        )
    md = [
        "| record | selected | held-out RMSE before -> after | held-out e_r % before -> after | remaining correlate |",
        "|---|---|---|---|---|",
    ]
    for r in rows:
        s = r["strongest_remaining_correlate"] or {}
        md.append(
            f"| {r['record']} | {', '.join(r['selected']) or 'none'} | {r['heldout_rmse_before']:.4g} -> {r['heldout_rmse_after']:.4g} | "
            f"{r['heldout_e_r_before']:.2f} -> {r['heldout_e_r_after']:.2f} | {s.get('signal')} ({s.get('corr', float('nan')):+.2f}) |"
        )
    atomic_write_json(out / "summary.json", rows)
    atomic_write_text(out / "summary.md", "\n".join(md) + "\n")
    print("\n".join(md))


if __name__ == "__main__":
    main()
