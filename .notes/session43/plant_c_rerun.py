"""Plant C (helper-1's trial-7 simulator): old auto (rNN/fit, session-42 code) vs new auto (rNN/fit_new) on the same
records: held-out (last 30 %) and new runs, RMSE over the true noise SD against the measured and the clean output."""
import glob, json, os, subprocess, sys, time
sys.path.insert(0, '/tmp/s43/trial7')
from score import score
T = '/tmp/s43/trial7'
rows = []
for n in [f'r{i:02d}' for i in range(1, 11)]:
    d = f'{T}/{n}'
    fit_new = f'{d}/fit_new'
    if not os.path.exists(f'{fit_new}/fit.json'):
        t0 = time.time()
        r = subprocess.run(['smafl', 'fit', f'{d}/{n}_first70.csv', '--out', fit_new, '--no-figures'], capture_output=True, text=True)
        open(f'{d}/fit_new_stderr.txt', 'w').write(r.stderr); open(f'{d}/fit_new_time.txt', 'w').write(f'{time.time()-t0:.1f}')
    row = {'rec': n}
    for tag, fit in (('old', f'{d}/fit'), ('new', fit_new)):
        doc = json.load(open(f'{fit}/fit.json'))
        row[f'{tag}_chosen'] = (doc['settings'].get('structure_choice') or {}).get('chosen')
        subprocess.run(['smafl', 'simulate', f'{fit}/fit.json', f'{d}/{n}_whole.csv', '--out', f'{d}/pred_{tag}.csv'], capture_output=True)
        s = score(f'{d}/pred_{tag}.csv', f'{d}/{n}_clean.npy', f'{d}/{n}_meta.json')
        row[f'{tag}_held'] = s['held_meas']; row[f'{tag}_held_clean'] = s['held_clean']; row[f'{tag}_train'] = s['train_meas']
        for sub in sorted(glob.glob(f'{d}/{n}[b-z]')):
            nn = os.path.basename(sub)
            if not os.path.exists(f'{sub}/{nn}_clean.npy'):
                continue
            subprocess.run(['smafl', 'simulate', f'{fit}/fit.json', f'{sub}/{nn}_whole.csv', '--out', f'{sub}/pred_{tag}.csv'], capture_output=True)
            s2 = score(f'{sub}/pred_{tag}.csv', f'{sub}/{nn}_clean.npy', f'{sub}/{nn}_meta.json', n70=0)
            row[f'{tag}_new_{nn}'] = s2['all_clean']
    rows.append(row); print(json.dumps(row), flush=True)
    json.dump(rows, open('/tmp/s43/pc/rows.json', 'w'), indent=1)
