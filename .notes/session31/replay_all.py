# Session 31: the lookalike rule replayed on every stored blind-diagnosis row under experiments/results (groups copied from the effect classes). python .notes/session31/replay_all.py
import json,glob,sys
FAM={'delay':{'timing'},'sensor_lag':{'timing'},'sensor_lead':{'timing'},'output_lag':{'timing'},'rate_dependence':{'timing'},
'resistance_tc':{'thermal'},'nonlinear_cooling':{'thermal'},'asymmetric_cooling':{'thermal'},'ambient_drift':{'thermal','slow'},
'creep':{'slow','timing'},'strain_accumulation':{'slow'},'input_warp':{'static'},'output_saturation':{'static'},'load_dependence':{'static'},'nonlocal_memory':{'memory'}}
tot=0; changed=0
for f in sorted(glob.glob('experiments/results/**/*.json', recursive=True)):
    try: d=json.load(open(f))
    except Exception: continue
    if not isinstance(d,dict) or 'rows' not in d: continue
    for r in d['rows']:
        if not isinstance(r,dict) or 'candidates' not in r or 'selected_new' not in r: continue
        tot+=1
        acc=sorted([c for c in r['candidates'] if c.get('accepted')], key=lambda c:c['heldout_rmse'])
        if not acc: continue
        amb=[c['name'] for c in acc if c['heldout_rmse']<=1.1*acc[0]['heldout_rmse']]
        common=set.intersection(*[FAM.get(n,{n}) for n in amb])
        if not common:
            changed+=1
            print(f.split('/')[-2][-22:], f.split('/')[-1][:28], 'truth', r['truth'], 'sel', r['selected_new'], 'amb', amb, '-> none')
print(tot, changed)
