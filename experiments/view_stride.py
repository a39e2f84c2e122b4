"""Default `smafl fit` on one independent record with the long-record view's stride cap set (issue 18, session 14).

    OPENBLAS_NUM_THREADS=1 python experiments/view_stride.py MAX_STRIDE SEED DRIVE RATE_HZ MINUTES START

prints one JSON line: fitted samples, stride used, seconds, train / held-out RMSE over the plant's noise SD (the
record's last 30 % held out, as `fit_record`'s default split).  MAX_STRIDE 10 gives the pre-session-14 rule on a
60 000-sample record (10 minutes at 100 Hz), 5 the current default.  The record comes from tests/indep_plant.py
(plain numpy, no smafl_jax import).
"""

import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
import indep_plant

import smafl_jax as sj
from smafl_jax.identify import _decimate  # private: the experiment moves the stride cap
from smafl_jax.report import fit_record


def main(argv):
    if len(argv) != 6:
        raise SystemExit(__doc__)
    max_stride, seed, drive, rate, minutes, start = int(argv[0]), int(argv[1]), argv[2], float(argv[3]), float(argv[4]), argv[5]
    _decimate.MAX_STRIDE = max_stride
    r = indep_plant.make_record(seed, drive=drive, rate_hz=rate, minutes=minutes, start=start)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "rec.csv"
        indep_plant.write_csv(path, r)
        rec = sj.load_record(path)
        t0 = time.perf_counter()
        model, doc, (_, _, yhat) = fit_record(rec)
        seconds = time.perf_counter() - t0
    h0, noise, y = r["heldout_start"], r["noise_sd"], np.asarray(rec.y)

    def rmse(sl):
        return float(np.sqrt(np.mean((yhat[sl] - y[sl]) ** 2)) / noise)

    row = {
        "max_stride": max_stride,
        "record": {"seed": seed, "drive": drive, "rate_hz": rate, "minutes": minutes, "start": start},
        "n": len(rec),
        "stride": (doc["settings"]["fit_view"] or {}).get("stride", 1),
        "seconds": round(seconds, 1),
        "train_over_noise": round(rmse(slice(0, h0)), 3),
        "heldout_over_noise": round(rmse(slice(h0, None)), 3),
        "k1": float(model.thermal.k1),
        "k1_true": r["truth"]["thermal"]["k1"],
    }
    print(json.dumps(row), flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
