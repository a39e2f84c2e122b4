import json, glob, os, sys, collections
res = sys.argv[1] if len(sys.argv) > 1 else '/tmp/s30/res'
rows = {}
for f in sorted(glob.glob(f'{res}/*_s*.json')):
    if f.endswith('.partial.json'):
        continue
    tag, rest = os.path.basename(f)[:-5].split('_', 1)
    truth, seed = rest.rsplit('_s', 1)
    d = json.load(open(f))
    for r in d['rows']:
        noise = r['case']['noise_rms_measured']
        rows[(truth, int(seed), tag)] = dict(sel=r['selected_new'], amb=r['ambiguous_new'], base=r['base_heldout_over_noise'],
                                             ext=r['extended_heldout_rmse_new'] / noise, sec=r['seconds'], drive=r['case']['drive'],
                                             start=r['case']['start'], var=r['case'].get('variant'))
# seed-1 old from session 29
for f in ['with_memory_search_a', 'with_memory_search_b']:
    d = json.load(open(f'/work/main/experiments/results/diagnose_independent_seed1_session29/{f}.json'))
    for r in d['rows']:
        noise = r['case']['noise_rms_measured']
        rows.setdefault((r['truth'], 1, 'old'), dict(sel=r['selected_new'], amb=r['ambiguous_new'], base=r['base_heldout_over_noise'],
                        ext=r['extended_heldout_rmse_new'] / noise, sec=r['seconds'], drive=r['case']['drive'], start=r['case']['start'], var=r['case'].get('variant')))
def ok(truth, r):
    if truth == 'none':
        return not r['sel']
    return truth in r['sel'] or truth in (r['amb'] or [])
tally = collections.defaultdict(lambda: [0, 0])
print('| truth | seed | drive, start, variant | old: selected (base -> ext / noise) | new: selected (base -> ext / noise) | s old/new |')
print('|---|---|---|---|---|---|')
for (truth, seed) in sorted({(t, s) for t, s, _ in rows}):
    o, n = rows.get((truth, seed, 'old')), rows.get((truth, seed, 'new'))
    def fmt(r):
        if r is None:
            return '-'
        sel = '+'.join(r['sel']) or 'none'
        if r['amb'] and len(r['amb']) > 1:
            sel += ' (ambiguous: ' + ', '.join(r['amb']) + ')'
        return f"{sel}{' ✓' if ok(truth, r) else ''} ({r['base']:.2f} -> {r['ext']:.2f})"
    sec = f"{o['sec']:.0f}/{n['sec']:.0f}" if o and n else '-'
    r0 = n or o
    print(f"| {truth} | {seed} | {r0['drive']}, {r0['start']}, {r0['var']} | {fmt(o)} | {fmt(n)} | {sec} |")
    for tag, r in (('old', o), ('new', n)):
        if r is not None and o is not None and n is not None:
            tally[(truth, tag)][0] += ok(truth, r)
            tally[(truth, tag)][1] += 1
print()
for truth in sorted({t for t, _ in tally}):
    print(truth, 'old %d/%d' % tuple(tally[(truth, 'old')]), 'new %d/%d' % tuple(tally[(truth, 'new')]))
