"""Probe: a delay (or other) record of the independent plant at a chosen rate; diagnose with a few candidate effects."""
import sys, json, time
root = sys.argv[1]
sys.path.insert(0, root); sys.path.insert(0, '/work/main/tests')
import numpy as np
import indep_plant as ip
import smafl_jax as sj
from smafl_jax.diagnosis import diagnose
effect, variant, seed, rate, minutes, drive, start = sys.argv[2], sys.argv[3], int(sys.argv[4]), float(sys.argv[5]), float(sys.argv[6]), sys.argv[7], sys.argv[8]
effects = sys.argv[9].split(',')
rec = ip.make_record(seed, effect=effect, variant=variant, drive=drive, rate_hz=rate, minutes=minutes, start=start)
path = ip.write_csv(f'/tmp/s32/probe/{effect}_{seed}_{int(rate)}.csv', rec)
noise = float(np.sqrt(np.mean((rec['y'] - rec['y_clean']) ** 2)))
print('record', path, rec['meta']['n'], 'effect', rec['truth']['effect']['params'] if rec['truth']['effect'] else None, 'over noise', rec['meta'].get('effect_delta_over_noise'), flush=True)
t0 = time.time()
res = diagnose(sj.load_record(path), effects=effects, refit=False, verbose=True, unexplained=False, n_null=8).report
print('base train %.2f held %.2f' % (res['base']['train_rmse'] / noise, res['base']['heldout_rmse'] / noise))
for c in res['candidates']:
    if c.get('fitted'):
        print(c['name'], 'train %.2f held %.2f gain %.3f' % (c['train_rmse'] / noise, c['heldout_rmse'] / noise, c['heldout_gain']), c.get('parameters'), c.get('decision'))
print('selected', res['selected'], 'time %.0f s' % (time.time() - t0))
