"""`--model auto` on a drive voltage with the Preisach cascade as a second candidate, on the plant-B records.

Reads the default fits (experiments/results/plant_b_default_fit.jsonl: the EUPI cascade, session 19) and the
`--model cascade-preisach` fits of the same records (experiments/results/plant_b_probes.jsonl, from
`python experiments/fit_plant_b.py --probe-args "--model cascade-preisach --max-steps 200" --only ...`), applies the rule
`--model auto` applies (the lower validation RMSE of the fit's own split, `report.choose_structure`) and scores the
chosen model on the held-out 30 % the fits never saw.  Both fits are the ones `smafl fit` makes of each class (the EUPI
cascade's path is unchanged by the second candidate), so the choice is the one the default fit makes.

    python experiments/plant_b_class_choice.py
"""

from __future__ import annotations

import json
import math
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "results"
SUFFIXES = (  # the latest code first: max-steps 50 = final session-20 code, 100 = before the warm refit, 200 = mixed
    "_model_cascade-preisach_max-steps_50",
    "_model_cascade-preisach_max-steps_100",
    "_model_cascade-preisach_max-steps_200",
)


def _gm(v):
    return math.exp(sum(math.log(x) for x in v) / len(v)) if v else float("nan")


def main() -> None:
    eupi = {}
    for line in (RESULTS / "plant_b_default_fit.jsonl").read_text().splitlines():
        d = json.loads(line)
        eupi[d["name"]] = d
    pre, rank = {}, {}
    for line in (RESULTS / "plant_b_probes.jsonl").read_text().splitlines():
        d = json.loads(line)
        for i, suf in enumerate(SUFFIXES):
            name = d["name"][: -len(suf)]
            if d["name"].endswith(suf) and d.get("returncode") == 0 and i <= rank.get(name, len(SUFFIXES)):
                pre[name], rank[name] = d, i  # the latest code's fit of the record (the last such line)
    rows = []
    print("| record | plant | EUPI cascade val / held-out | Preisach cascade val / held-out | auto chooses | held-out |")
    print("|---|---|---|---|---|---|")
    for name, e in eupi.items():
        p = pre.get(name)
        if p is None:
            continue
        ve, vp = e["fit"]["val_rmse"], p["fit"]["val_rmse"]
        choice = "preisach" if vp < ve else "eupi"
        held = p["heldout_x_noise"] if choice == "preisach" else e["heldout_x_noise"]
        rows.append((name, e["truth"]["hysteresis"], e["heldout_x_noise"], p["heldout_x_noise"], held, e["wall_s"], p["wall_s"]))
        print(
            f"| {name} | {e['truth']['hysteresis']} | {ve:.4g} / {e['heldout_x_noise']:.2f}x | {vp:.4g} / "
            f"{p['heldout_x_noise']:.2f}x | {choice} | {held:.2f}x |"
        )
    n = len(rows)
    for label, i in (("EUPI cascade (session 19 default)", 2), ("Preisach cascade", 3), ("auto (both, validation)", 4)):
        v = [r[i] for r in rows]
        print(
            f"{label}: geometric mean {_gm(v):.2f}x noise, within 3x {sum(x <= 3 for x in v)}/{n}, within 1.5x {sum(x <= 1.5 for x in v)}/{n}"
        )
    for cls in ("preisach", "ikuta"):
        sub = [r for r in rows if r[1] == cls]
        print(f"  {cls} plants ({len(sub)}): EUPI {_gm([r[2] for r in sub]):.2f}x -> auto {_gm([r[4] for r in sub]):.2f}x")
    worse = [r for r in rows if r[4] > 1.1 * r[2]]
    print(
        f"auto worse than the EUPI cascade by > 10 %: {len(worse)}/{n}: "
        + ", ".join(f"{r[0]} {r[2]:.2f} -> {r[4]:.2f}" for r in worse)
    )
    print(
        f"fit seconds (the two classes fitted one after the other, a loaded 2-core machine): EUPI {sum(r[5] for r in rows):.0f} s, Preisach {sum(r[6] for r in rows):.0f} s"
    )


if __name__ == "__main__":
    main()
