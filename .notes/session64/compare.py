"""Session 64 vs stored results on the same records: selection, and fold flags of candidates that reached the folds.
python compare.py NEWDIR OLDDIR..."""
import glob, json, os, sys
def load(dirs):
    out = {}
    for d in dirs:
        for f in sorted(glob.glob(f'{d}/**/*.json', recursive=True)):
            if f.endswith('.partial.json'): continue
            try: rows = json.load(open(f))['rows']
            except (KeyError, json.JSONDecodeError, TypeError): continue
            for r in rows:
                out.setdefault((r['truth'], r['case']['requested_seed']), r)
    return out
new = load([sys.argv[1]]); old = load(sys.argv[2:])
ok_o = ok_n = 0; n = 0
for k in sorted(new):
    r = new[k]; o = old.get(k)
    t = r['truth']
    def right(sel): return (not sel) if t == 'none' else (t in (sel or []))
    so = o['selected_new'] if o else None
    n += 1; ok_n += right(r['selected_new']); ok_o += right(so) if o else 0
    flag = '' if o and so == r['selected_new'] else '  <-- CHANGED'
    print(f"{t:20s} s{k[1]:<6} old {so} new {r['selected_new']} right {right(so) if o else '-'}->{right(r['selected_new'])}{flag}")
    for x in r['candidates']:
        cal = x.get('calibration') or {}
        if 'folds' in cal:
            fl = [(round(f['gain'], 2), round(max(f.get('undetermined_before', 0), f.get('undetermined_after', 0)), 2)) for f in cal['folds']]
            print(f"      {x['name']:20s} folds {fl} gate {cal['gates'].get('folds')} acc {cal.get('accepted')} {cal.get('reason','')[:80]}")
print(f"right: old {ok_o} new {ok_n} of {n}")
