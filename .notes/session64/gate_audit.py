import glob, json, os, sys, collections
seen=set(); stat=collections.Counter()
for d in sys.argv[1:]:
    for f in sorted(glob.glob(f'{d}/*.json')):
        if f.endswith('.partial.json'): continue
        try: rows=json.load(open(f))['rows']
        except (KeyError, json.JSONDecodeError, TypeError): continue
        for r in rows:
            c=r['case']; key=(r['truth'],c['requested_seed'])
            if key in seen or r['truth']=='none': continue
            seen.add(key)
            cands={x['name']:x for x in r['candidates']}
            t=cands.get(r['truth'])
            if t is None: why='not a candidate'
            else:
                cal=t.get('calibration') or {}
                if t.get('accepted'): why='accepted'
                else:
                    g=cal.get('gates',{})
                    failed=[k for k,v in g.items() if not v]
                    why='failed '+(','.join(failed) or '?')
                why += f" gain {t.get('heldout_gain',float('nan')):.2f}"
            ok = r['truth'] in (r['selected_new'] or [])
            print(f"{r['truth']:20s} s{c['requested_seed']:<5} sel={r['selected_new']} ok={ok} truth: {why} base {r.get('base_heldout_over_noise',0):.1f}x  {os.path.basename(d)}")
