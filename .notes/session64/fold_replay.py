"""Candidates whose fold verdict the session-64 rule changed (replayed: the old rule on the same fold gains)."""
import glob, json, sys
sys.path.insert(0, ".")
from smafl_jax.diagnosis import folds_gate
n_c = n_f = 0
for f in sorted(glob.glob(f'{sys.argv[1]}/**/*.json', recursive=True)):
    if f.endswith('.partial.json'): continue
    try: rows = json.load(open(f))['rows']
    except (KeyError, json.JSONDecodeError, TypeError): continue
    for r in rows:
        for x in r['candidates']:
            cal = x.get('calibration') or {}
            if 'folds' not in cal: continue
            n_c += 1
            g = [fo['gain'] for fo in cal['folds']]; d = [fo['determined'] for fo in cal['folds']]
            n_f += sum(not v for v in d)
            old = folds_gate(g, 0.05)[0]; new = cal['gates']['folds']
            if old != new:
                print(f"{r['truth']:18s} s{r['case']['requested_seed']:<6} {x['name']:20s} folds {[round(v,2) for v in g]} undetermined {[round(max(fo['undetermined_before'], fo['undetermined_after']),2) for fo in cal['folds']]} old {old} -> new {new}; final accepted {cal.get('accepted')} ({cal.get('reason','')[:60]}); selected {r['selected_new']}")
print(f"{n_c} fold tests, {n_f} undetermined folds")
