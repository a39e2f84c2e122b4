"""Session 63: candidates of stored blind diagnoses that reached the fold gate; their fold gains and the outcome.
python .notes/session63/fold_gate_audit.py DIR [DIR ...]"""
import glob, json, os, sys
seen = set()
for d in sys.argv[1:]:
    for f in sorted(glob.glob(f'{d}/*.json')):
        if f.endswith('.partial.json') or 'README' in f:
            continue
        try:
            rows = json.load(open(f))['rows']
        except (KeyError, json.JSONDecodeError, TypeError):
            continue
        for r in rows:
            c = r['case']
            key = (r['truth'], c['requested_seed'])
            if key in seen:
                continue
            seen.add(key)
            for x in r['candidates']:
                cal = x.get('calibration') or {}
                if 'folds' not in cal:
                    continue
                g = [round(fo['gain'], 2) for fo in cal['folds']]
                null = cal.get('null')
                print(f"{r['truth']:18s} s{c['requested_seed']:<5} base {r['base_train_over_noise']:.2f}/{r['base_heldout_over_noise']:.2f} "
                      f"{x['name']:20s} gain {x['heldout_gain']:.2f} folds {g} "
                      f"{'null thr %.2f' % null['threshold'] if null else 'null -'} acc={x.get('accepted')} sel={r['selected_new']} {os.path.basename(d)}")
