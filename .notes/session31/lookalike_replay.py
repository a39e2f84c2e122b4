"""Session 31: the selection with and without the lookalike rule, replayed on stored blind-diagnosis records (each
record's candidates, their calibrated decisions and held-out RMSEs are in the JSON; only the last step differs).
python .notes/session31/lookalike_replay.py DIR [DIR ...]   (prints one row per record and the tallies)"""
import glob, json, os, sys, collections
sys.path.insert(0, os.path.join(os.path.dirname(__file__), '..', '..'))
from smafl_jax.diagnosis import lookalike_groups

AMBIGUITY = 0.10


def decide(r):
    acc = sorted([c for c in r['candidates'] if c.get('accepted')], key=lambda c: c['heldout_rmse'])
    if not acc:
        return [], [], []
    amb = [c['name'] for c in acc if c['heldout_rmse'] <= (1 + AMBIGUITY) * acc[0]['heldout_rmse']]
    old = [acc[0]['name']]
    new = old if lookalike_groups(amb) else []
    return old, new, amb


def named(truth, sel, amb):
    return (not sel) if truth == 'none' else bool(sel) and (truth in sel or truth in amb)


tally = collections.Counter()
print('| truth | seed | drive, start, variant | base train / held-out (noise) | accepted within 10 % | without the rule | with it |')
print('|---|---|---|---|---|---|---|')
for d in sys.argv[1:]:
    for f in sorted(glob.glob(f'{d}/new_*_s*.json')):
        for r in json.load(open(f))['rows']:
            old, new, amb = decide(r)
            c = r['case']
            seed = os.path.basename(f)[:-5].rsplit('_s', 1)[1]
            ok_old, ok_new = named(r['truth'], old, amb), named(r['truth'], new, amb)
            tally['records'] += 1
            tally['old named'] += ok_old
            tally['new named'] += ok_new
            tally['old wrong'] += bool(old) and not ok_old
            tally['new wrong'] += bool(new) and not ok_new
            if r['truth'] == 'none':
                tally['clean'] += 1
                tally['old clean none'] += ok_old
                tally['new clean none'] += ok_new
            print(f"| {r['truth']} | {seed} | {c['drive']}, {c['start']}, {c.get('variant')} | {r['base_train_over_noise']:.2f} / "
                  f"{r['base_heldout_over_noise']:.2f} | {', '.join(amb) or '-'} | {'+'.join(old) or 'none'}{' ✓' if ok_old else ''} | "
                  f"{'+'.join(new) or 'none'}{' ✓' if ok_new else ''} |")
print()
print(dict(tally))
