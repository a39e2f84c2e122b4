import sys, json, numpy as np
sys.path[:0]=[__import__('os').path.dirname(__import__('os').path.abspath(__file__)),'/work/main/experiments','/work/main/tests']
KIND=sys.argv[1]
import indep_plant_b as pb, fit_plant_b as fb
if KIND!='gauss':
    sys.argv=[sys.argv[0],KIND,'0','/dev/null']; import alt_density
from hybrid import fits
out=open('hybrid.jsonl','a')
cases=[('steps',25,'mid'),('triangle',5,'warm'),('pwm',25,'cold'),('multisine',25,'cold'),('triangle',25,'mid'),('steps',5,'warm')]
for seed in (11,12):
    for drive,rate,start in cases:
        rec=pb.make_record(seed, drive=drive, rate_hz=rate, start=start, hysteresis='preisach'); tr=rec['truth']
        step=max(1,int(rate//5)); T=tr['temperature'][::step]; y=rec['output'][::step]; sd=rec['noise_sd']; h0=int(round(0.7*T.size))
        p, hy = fits(T, y, h0)
        e=lambda q,s: float(np.sqrt(np.mean((q[s]-y[s])**2))/sd)
        row=dict(kind=KIND,seed=seed,case=f'{drive}_{rate}_{start}',param=[e(p,slice(0,h0)),e(p,slice(h0,None))],
                 hybrid={str(l):[e(q,slice(0,h0)),e(q,slice(h0,None))] for l,q in hy.items()})
        print(KIND, seed, row['case'], 'param %.2f/%.2f'%tuple(row['param']), ' '.join('%s:%.2f/%.2f'%(l,*v) for l,v in row['hybrid'].items()), flush=True)
        out.write(json.dumps(row)+'\n'); out.flush()
