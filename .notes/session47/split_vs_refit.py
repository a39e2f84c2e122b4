"""Plant B session-46 fits: held-out error of the deployed (whole-record refit) model vs the split model, both simulated from t=0."""
import sys, json, glob, numpy as np
import smafl_jax as sj, jax.numpy as jnp
from smafl_jax import model_from_dict
rows = []
for d in sorted(glob.glob('/tmp/s46/pb2[23]/s*') + glob.glob('/tmp/s46/pbx/s*')):
    try:
        doc = json.load(open(d + '/fit/fit.json')); p = np.load(d + '/pred.npz')
    except (FileNotFoundError, NotADirectoryError):
        continue
    if doc.get('split_model') is None: continue
    u, y, yc, h0 = p['u'], p['y'], p['yc'], int(p['h0'])
    dt = float(np.loadtxt(d + '/full.csv', delimiter=',', skiprows=1, max_rows=2)[1, 0])
    sd = float(doc['metrics'].get('noise', {}).get('sd', 0.005)) if isinstance(doc['metrics'].get('noise'), dict) else 0.005
    name = d.split('/')[-1]; sd = 0.02 if 'n0.02' in name else 0.005
    out = {}
    for key in ('model', 'split_model'):
        m = model_from_dict(doc[key])
        yh = np.asarray(sj.simulate(m, jnp.asarray(u), dt))
        out[key] = (np.sqrt(np.mean((yh[:h0] - y[:h0])**2)) / sd, np.sqrt(np.mean((yh[h0:] - y[h0:])**2)) / sd)
    print(f"{name:40s} refit train {out['model'][0]:7.2f} held {out['model'][1]:7.2f} | split train {out['split_model'][0]:7.2f} held {out['split_model'][1]:7.2f}", flush=True)
