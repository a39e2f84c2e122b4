import json, glob, numpy as np, collections
rows=[]
for f in glob.glob('experiments/results/class_choice_phase_session54/*.jsonl')+glob.glob('experiments/results/class_choice_coverage_session28/*.jsonl'):
    for l in open(f):
        r=json.loads(l); r['file']=f.split('/')[-1]; rows.append(r)
g=collections.defaultdict(dict)
for r in rows: g[(r['file'],r['cell'],r['seed'])][r['cls']]=r
W=0.5
res=collections.defaultdict(list)
for k,c in g.items():
    if 'cascade' not in c or len(c)<2: continue
    cov=[v['coverage'] for v in c.values() if v['coverage'] is not None]
    unc = bool(cov) and max(cov) < W
    best=min(c, key=lambda n: c[n]['val_rmse'])
    d=c['cascade']
    if d['val_rmse']<2*c[best]['val_rmse'] and d['train_rmse']<=c[best]['train_rmse']: best='cascade'
    tr=min(c, key=lambda n: c[n]['train_rmse'])
    orc=min(c, key=lambda n: c[n]['held_x'])
    med=None
    key='unc' if unc else 'cov'
    res[key+'_val'].append(c[best]['held_x']); res[key+'_train'].append(c[tr]['held_x']); res[key+'_default'].append(d['held_x']); res[key+'_oracle'].append(c[orc]['held_x'])
    for n in c:
        res[key+'_'+n].append(c[n]['held_x'])
for k in sorted(res):
    v=np.array(res[k]); print(k, len(v), 'gm %.2f'%np.exp(np.mean(np.log(v))), 'within1.5 %d'%np.sum(v<=1.5))
