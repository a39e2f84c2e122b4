"""Issue 14: `check_record` on records this toolkit did not make, clean and with planted faults.

Records come from the independent numpy plant (tests/indep_plant.py, no smafl_jax inside it): every drive family,
5 / 25 / 100 Hz, displacement and length sensors, cold and warm starts.  For each clean record the findings are
counted (each one a false alarm); then one fault is planted in a copy of the same record and the detector must name
it, at its place:

- ``zeroing``: the output offset by 10-50 % of its range from a random sample to the end of the record (a sensor
  re-zeroed or knocked; the kind the cavatappi 200 g file shows), planted only where the input holds for the
  10 samples on each side of it (`check_record` judges a jump only while the input holds: elsewhere the plant
  itself moves and the jump is not a sensor fault one can tell);
- ``spike``: 1-3 output samples off by 10-50 % of the range (a loose contact).

Run:  python experiments/data_checks_independent.py [SEEDS]     (default 4 seeds: 4 x 7 x 3 x 2 x 2 = 336 records)
"""

import collections
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
import indep_plant as ip  # noqa: E402

from smafl_jax.data import Record, check_record  # noqa: E402


def _record(r, y):
    return Record.from_arrays(r["time"], r["u"], y, name="rec", input_name="voltage_V", output_name="displacement_mm")


def _hold_points(u, rng_u, w=10):
    """Samples k whose 10 neighbours on each side hold the input within 1 % of its range."""
    n = u.size
    ok = [k for k in range(w, n - w) if np.ptp(u[k - w : k + w]) <= 0.01 * rng_u]
    return np.asarray(ok, int)


#: Bins of a planted fault's size in noise standard deviations (the detectors' thresholds are 8-10 robust scales).
BINS = ((0, 8), (8, 15), (15, 30), (30, np.inf))


def _tally(by_size, kind, z, hit):
    lo = next(lo for lo, hi in BINS if lo <= z < hi)
    by_size[(kind, lo)][0] += bool(hit)
    by_size[(kind, lo)][1] += 1


def main(n_seeds=4):
    clean_alarms, counts = collections.Counter(), collections.Counter()
    found = collections.Counter()
    by_size = collections.defaultdict(lambda: [0, 0])  # (kind, size bin in noise SDs) -> [found, planted]
    rng = np.random.default_rng(0)
    for seed in range(n_seeds):
        for fam in ip.FAMILIES:
            for rate in (5, 25, 100):
                for ori in ("displacement", "length"):
                    for start in ("cold", "warm"):
                        r = ip.make_record(seed, drive=fam, rate_hz=rate, minutes=5, start=start, orientation=ori)
                        y = np.asarray(r["y"], float)
                        span = float(np.percentile(y, 99) - np.percentile(y, 1))
                        counts["clean"] += 1
                        for f in check_record(_record(r, y)):
                            clean_alarms[(f.kind, fam, rate)] += 1
                        # a spike somewhere in the middle
                        k = int(rng.integers(y.size // 10, 9 * y.size // 10))
                        w = int(rng.integers(1, 4))
                        ys = y.copy()
                        size = rng.choice([-1, 1]) * rng.uniform(0.1, 0.5) * span
                        ys[k : k + w] += size
                        got = check_record(_record(r, ys))
                        counts["spike"] += 1
                        hit = any(f.kind == "spike" and f.index[0] <= k + w and f.index[1] >= k for f in got)
                        found["spike"] += hit
                        _tally(by_size, "spike", abs(size) / r["noise_sd"], hit)
                        # a zeroing step where the input holds
                        u = np.asarray(r["u"], float)
                        holds = _hold_points(u, float(np.ptp(u)) or 1.0)
                        if holds.size:
                            k = int(rng.choice(holds))
                            yz = y.copy()
                            size = rng.choice([-1, 1]) * rng.uniform(0.1, 0.5) * span
                            yz[k:] += size
                            got = check_record(_record(r, yz))
                            counts["zeroing"] += 1
                            # the finding covers the shorter side of the step: it starts or ends at the step
                            hit = any(f.kind == "offset_jump" and min(abs(i - k) for i in f.index) <= 2 for f in got)
                            found["zeroing"] += hit
                            _tally(by_size, "zeroing", abs(size) / r["noise_sd"], hit)
        print(f"seed {seed} done: {dict(counts)}", file=sys.stderr, flush=True)
    n_alarms = sum(clean_alarms.values())
    print(f"clean records: {counts['clean']}, findings on them (false alarms): {n_alarms}")
    for key, v in sorted(clean_alarms.items()):
        print(f"  {v} x {key}")
    for kind in ("spike", "zeroing"):
        print(f"planted {kind}: found at its place in {found[kind]} of {counts[kind]}")
        for lo, hi in BINS:
            f, n = by_size[(kind, lo)]
            if n:
                print(f"  size {lo:g}-{hi:g} noise SD: {f} of {n}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 4)
