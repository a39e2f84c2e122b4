"""Probe: diagnose one independent-effect record with a subset of candidate effects; print base / candidate figures."""
import sys, json
sys.path.insert(0, sys.argv[1]); sys.path.insert(0, sys.argv[1] + '/experiments')
import indep_effects as ie
import smafl_jax as sj
from smafl_jax.diagnosis import diagnose
truth, seed = sys.argv[2], int(sys.argv[3])
effects = sys.argv[4].split(',')
path, case = ie.write_effect_record('/tmp/s30/probe', truth, seed)
rec = sj.load_record(path)
res = diagnose(rec, effects=effects, refit=False, verbose=True, unexplained=False, n_null=8).report
noise = case['noise_rms_measured']
print('case', {k: case.get(k) for k in ('drive', 'start', 'variant', 'n', 'effect_params')})
print('base train %.2f held %.2f' % (res['base']['train_rmse'] / noise, res['base']['heldout_rmse'] / noise))
for c in res['candidates']:
    if c.get('fitted'):
        print(c['name'], 'train %.2f held %.2f gain %.3f' % (c['train_rmse'] / noise, c['heldout_rmse'] / noise, c['heldout_gain']), c.get('parameters'), c.get('decision'), {k: c['fit'].get(k) for k in ('start', 'train_sse_from_profiled_base', 'train_sse_from_refined_base')})
print('selected', res['selected'])
