import json, glob, numpy as np
files = sorted(set(glob.glob('experiments/results/**/*.json', recursive=True)))
rows = []
seen = set()
for f in files:
    try:
        d = json.load(open(f))
    except Exception:
        continue
    rs = d.get('rows') if isinstance(d, dict) else None
    if not isinstance(rs, list):
        continue
    for r in rs:
        if not isinstance(r, dict) or 'candidates' not in r:
            continue
        truth = r.get('truth')
        for c in r['candidates'] or []:
            cal = c.get('calibration') or {}
            folds = cal.get('folds')
            if not folds:
                continue
            g = [x['gain'] for x in folds]
            key = (truth, c['name'], tuple(round(x, 6) for x in g))
            if key in seen:
                continue
            seen.add(key)
            rows.append((f, truth, c['name'], g, cal.get('gates', {}), cal.get('accepted')))
print(len(rows), 'fold records')
def rule_mean(g): return sum(x > 0 for x in g) >= len(g) - 1 and np.mean(g) > 0
def rule_clip(g, lo=-1): return sum(x > 0 for x in g) >= len(g) - 1 and np.mean(np.clip(g, lo, None)) > 0
def rule_pos(g): return sum(x > 0 for x in g) >= len(g) - 1
for name, rule in [('mean', rule_mean), ('clip-1', rule_clip), ('clip-0.5', lambda g: rule_clip(g, -0.5)), ('2of3', rule_pos)]:
    ok = [r for r in rows if rule(r[3])]
    right = [r for r in ok if r[1] == r[2] or (r[1] == 'output_lag' and r[2] == 'output_lag')]
    print(f"{name:9s} pass {len(ok):3d}  truth {len(right):3d}  wrong {len(ok)-len(right):3d}  (on none {sum(r[1]=='none' for r in ok)})")
for r in rows:
    if rule_clip(r[3]) and not rule_mean(r[3]):
        print('  clip admits', r[1], r[2], [round(x,2) for x in r[3]], r[0].split('/')[-1])
