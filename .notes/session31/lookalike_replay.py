"""Session 31: the last steps of the calibrated selection replayed on stored blind-diagnosis records (each record's
candidates, their gates and held-out RMSEs are in the JSON), three ways: (a) the session-30 rule (best accepted
candidate), (b) + the lookalike rule (nothing when the accepted candidates within 10 % of the best share no group),
(c) + the folds' mean gain at least min_gain (5 %) (a candidate whose fold mean is below it is rejected).
python .notes/session31/lookalike_replay.py DIR [DIR ...]   (one row per record, then the tallies)"""
import glob, json, os, sys, collections
sys.path.insert(0, os.path.join(os.path.dirname(__file__), '..', '..'))
from smafl_jax.diagnosis import lookalike_groups

AMBIGUITY, MIN_GAIN = 0.10, 0.05


def mean_fold(c):
    cal = c.get('calibration') or {}
    return cal.get('mean_fold_gain', cal.get('mean_fold_gain_raw'))


def decide(acc, lookalikes):
    acc = sorted(acc, key=lambda c: c['heldout_rmse'])
    if not acc:
        return [], []
    amb = [c['name'] for c in acc if c['heldout_rmse'] <= (1 + AMBIGUITY) * acc[0]['heldout_rmse']]
    return ([acc[0]['name']] if not lookalikes or lookalike_groups(amb) else []), amb


def named(truth, sel, amb):
    return (not sel) if truth == 'none' else bool(sel) and (truth in sel or truth in amb)


tally = collections.Counter()
seen = set()
print('| truth | seed | drive, start, variant | base train / held-out (noise) | accepted (gain, fold mean) | (a) session 30 | (b) + lookalikes | (c) + fold mean >= 5 % |')
print('|---|---|---|---|---|---|---|---|')
for d in sys.argv[1:]:
    for f in sorted(glob.glob(f'{d}/new_*_s*.json')):
        if f.endswith('.partial.json'):
            continue
        for r in json.load(open(f))['rows']:
            c = r['case']
            seed = os.path.basename(f)[:-5].rsplit('_s', 1)[1]
            key = (r['truth'], seed)
            acc = [x for x in r['candidates'] if x.get('accepted')]
            acc_c = [x for x in acc if mean_fold(x) is None or mean_fold(x) >= MIN_GAIN]
            cols = []
            for i, (a, look) in enumerate(((acc, False), (acc, True), (acc_c, True))):
                sel, amb = decide(a, look)
                if sel and r['selected_new'][:1] == sel:
                    sel = r['selected_new']  # the live run's second effect, added after the same first one
                ok = named(r['truth'], sel, amb)
                if key not in seen:
                    tally[(i, 'named')] += ok
                    tally[(i, 'wrong')] += bool(sel) and not ok
                    if r['truth'] == 'none':
                        tally[(i, 'clean none')] += ok
                cols.append(f"{'+'.join(sel) or 'none'}{' ✓' if ok else ''}")
            if key not in seen:
                tally['records'] += 1
                tally['clean'] += r['truth'] == 'none'
            seen.add(key)
            accs = ', '.join(f"{x['name']} {x['heldout_gain']:.2f}/{mean_fold(x) if mean_fold(x) is None else round(mean_fold(x), 2)}" for x in sorted(acc, key=lambda x: x['heldout_rmse'])) or '-'
            print(f"| {r['truth']} | {seed} | {c['drive']}, {c['start']}, {c.get('variant')} | {r['base_train_over_noise']:.2f} / "
                  f"{r['base_heldout_over_noise']:.2f} | {accs} | " + ' | '.join(cols) + ' |')
print()
n, k = tally['records'], tally['clean']
for i, lab in enumerate(('(a) session 30', '(b) + lookalikes', '(c) + fold mean >= 5 %')):
    print(f"{lab}: truth named {tally[(i, 'named')]}/{n}, wrong effect {tally[(i, 'wrong')]}, clean nothing selected {tally[(i, 'clean none')]}/{k}")
