"""Session 73: the blind tally split by how much structure the base leaves (newest run of each record, common.newest):
excess = sqrt(max(train^2 - 1, 0)) where train = base training RMSE / noise SD, i.e. the RMS of what the base cannot
fit, in noise SDs; and where the truth ranks on the whole record.
python .notes/session73/floor_split.py [EXTRA_DIR ...]"""
import collections, math, sys
sys.path.insert(0, ".notes/session73")
from common import newest, ok  # noqa: E402

bins = collections.defaultdict(lambda: [0, 0])
print("| truth | seed | base train / noise | held out / noise | excess | truth's whole-record rank (gain) | answer |")
print("|---|---|---|---|---|---|---|")
for truth, s_, r, (s, a), _ in newest(sys.argv[1:]):
    if truth == "none":
        continue
    k = ok(truth, s, a)
    tr, ho = r["base_train_over_noise"], r["base_heldout_over_noise"]
    ex = math.sqrt(max(tr * tr - 1, 0))
    ranking = (r.get("naming") or {}).get("ranking") or []
    rk, g = [x["name"] for x in ranking], {x["name"]: x["gain"] for x in ranking}
    where = f"{rk.index(truth) + 1} ({g[truth]:+.3f})" if truth in rk else "-"
    b = "excess < 1 noise SD" if ex < 1 else "excess >= 1 noise SD"
    bins[b][0] += k
    bins[b][1] += 1
    print(f"| {truth} | {s_} | {tr:.2f} | {ho:.2f} | {ex:.2f} | {where} | {'+'.join(s) or 'none'} {'ok' if k else '--'} |")
for b, (k, n) in sorted(bins.items()):
    print(f"{b}: {k}/{n} right")
