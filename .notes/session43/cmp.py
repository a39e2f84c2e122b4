# python .notes/session43/cmp.py (from .notes/session43): --model cascade on the default vs the sparse grid, and the lower validation RMSE of the two
import json

import numpy as np

a=[json.loads(l) for l in open('matrix_cascade_default_grid.jsonl')]
b={ (r['cell'],r['seed']):r for f in ['matrix_cascade_sparse_grid.jsonl'] for r in map(json.loads,open(f))}
rows=[]
for x in a:
    y=b[(x['cell'],x['seed'])]
    pick = y if y['val'] < x['val'] else x
    rows.append((x,y,pick))
    print(f"{x['cell'][:30]:30s} {x['seed']:3d} def {x['train']:5.2f}/{x['val']:6.2f}/{x['held']:6.2f}  small {y['train']:5.2f}/{y['val']:6.2f}/{y['held']:6.2f}  -> {'S' if pick is y else 'D'} {pick['held']:6.2f}")
for lab,k in (('default',0),('small',1),('val-chosen',2)):
    h=np.array([r[k]['held'] for r in rows]); print(f"{lab:10s} gm {np.exp(np.mean(np.log(h))):.2f} w1.5 {(h<=1.5).sum()} w3 {(h<=3).sum()} max {h.max():.1f}")
