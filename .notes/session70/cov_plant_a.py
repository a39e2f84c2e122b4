"""Session 70: time-block input coverage of clean plant-A records (which ones `--split auto` would interleave).
python .notes/session70/cov_plant_a.py 301 330"""
import sys
sys.path.insert(0, "tests")
import indep_plant as ip  # noqa: E402
import smafl_jax as sj  # noqa: E402
from smafl_jax.data import split as S  # noqa: E402

for seed in range(int(sys.argv[1]), int(sys.argv[2]) + 1):
    r = ip.make_record(seed, minutes=10.0)
    import tempfile, os
    with tempfile.TemporaryDirectory() as d:
        p = os.path.join(d, "a.csv")
        ip.write_csv(p, r)
        rec = sj.load_record(p)
    c = S.coverage(S.time_block(rec))["covered_fraction"]
    k = S.make_split(rec, "auto").kind
    print(seed, r["meta"]["drive"], round(c, 2), k, flush=True)
