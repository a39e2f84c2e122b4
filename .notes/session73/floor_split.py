"""Session 73: the blind tally split by how much structure the base leaves (seeds 10-14, newest run of each
record as in tally.py): excess = sqrt(max(train^2 - 1, 0)) where train = base training RMSE / noise SD, i.e. the
RMS of what the base cannot fit, in noise SDs. Also where the truth ranks on the whole record.
python .notes/session73/floor_split.py [EXTRA_DIR ...]"""
import collections, io, contextlib, math, sys
sys.path.insert(0, ".notes/session70")
sys.path.insert(0, ".notes/session67")
from paired import rows, answer, ok  # noqa: E402

with contextlib.redirect_stdout(io.StringIO()):
    import tally_auto as ta  # noqa: E402

R = "experiments/results/"
newer = {}
for d in [R + "diagnose_independent_session72/bound_retry"] + sys.argv[1:]:
    newer.update(rows(d))
bins = collections.defaultdict(lambda: [0, 0])
print("| truth | seed | base train / noise | held out / noise | excess | truth's whole-record rank (gain) | answer |")
print("|---|---|---|---|---|---|---|")
for (truth, seed), r in sorted(ta.old.items()):
    s_ = seed - 1000 * ta.TRUTHS.index(truth)
    if truth == "none" or not 10 <= s_ <= 14:
        continue
    fresh = newer.get((truth, seed)) or ta.auto.get((truth, seed))
    s, a = answer(fresh, 5.0) if fresh else (ta.floor.get((truth, seed)) or answer(r, 5.0))
    r = fresh or r
    k = ok(truth, s, a)
    tr, ho = r["base_train_over_noise"], r["base_heldout_over_noise"]
    ex = math.sqrt(max(tr * tr - 1, 0))
    rk = [x["name"] for x in (r.get("naming") or {}).get("ranking") or []]
    g = {x["name"]: x["gain"] for x in (r.get("naming") or {}).get("ranking") or []}
    where = f"{rk.index(truth) + 1} ({g[truth]:+.3f})" if truth in rk else "-"
    b = "excess < 1 noise SD" if ex < 1 else "excess >= 1 noise SD"
    bins[b][0] += k
    bins[b][1] += 1
    print(f"| {truth} | {s_} | {tr:.2f} | {ho:.2f} | {ex:.2f} | {where} | {'+'.join(s) or 'none'} {'ok' if k else '--'} |")
for b, (k, n) in sorted(bins.items()):
    print(f"{b}: {k}/{n} right")
