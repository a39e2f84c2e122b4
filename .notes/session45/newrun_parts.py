import json, numpy as np, smafl_jax as sj, sys
from smafl_jax.models._eupi import poly_columns
fit, train_csv, new_csv = sys.argv[1:4]
d = json.load(open(fit)); m = sj.model_from_dict(d['model'])
print(json.dumps({k: v for k, v in d['model']['thermal'].items()}), d['model']['hysteresis'].get('poly'), d['model']['hysteresis'].get('gain'), d['model']['hysteresis'].get('offset'), d['model']['hysteresis'].get('init'))
H = m.hysteresis
def parts(csv):
    rec = sj.load_record(csv)
    x = np.asarray(m.hysteresis_input(rec.u, rec.dt)); s = np.asarray(H.normalise(x))
    ops = np.asarray(H.operators(x)); w = np.concatenate([np.asarray(H.v), np.ravel(np.asarray(H.w))])
    poly = np.asarray(poly_columns(s, len(H.poly)) @ np.asarray(H.poly)) if hasattr(sj, 'models') else None
    return s, ops * w, poly, rec
s0, c0, p0, r0 = parts(train_csv); s1, c1, p1, r1 = parts(new_csv)
print('s train %.3f..%.3f new %.3f..%.3f' % (s0.min(), s0.max(), s1.min(), s1.max()))
print('poly train %.3f..%.3f new %.3f..%.3f' % (p0.min(), p0.max(), p1.min(), p1.max()))
print('lin gain*s train %.3f..%.3f new %.3f..%.3f'%(H.gain*s0.min(), H.gain*s0.max(), H.gain*s1.min(), H.gain*s1.max()))
r, a = [np.asarray(q) for q in H._bank()]
for i in range(c0.shape[1]):
    if np.ptp(c0[:, i]) + np.ptp(c1[:, i]) < 1e-6: continue
    print(i, 'r %.3f a %.2f' % (r[i], a[i]), 'train %.3f..%.3f new %.3f..%.3f' % (c0[:, i].min(), c0[:, i].max(), c1[:, i].min(), c1[:, i].max()))
