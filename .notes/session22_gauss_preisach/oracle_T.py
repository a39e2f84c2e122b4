"""Oracle: the toolkit's Preisach (static) fitted on the plant's TRUE temperature -> is held-out error thermal or hysteresis?"""
import sys, json, subprocess, numpy as np, os
sys.path[:0]=['/work/main/experiments','/work/main/tests']
import fit_plant_b as fb, indep_plant_b as pb
import smafl_jax as sj
names=sys.argv[1].split(',')
out=open(sys.argv[2],'a')
for c in fb.grid([4,5],10.0)[:-3]:
    n=fb.name_of(c)
    if n not in names: continue
    rec=pb.make_record(**c); tr=rec['truth']; h0=rec['heldout_start']; sd=rec['noise_sd']
    d=f'oracle/{n}'; os.makedirs(d,exist_ok=True)
    T=tr['temperature']; y=rec['output']; t=rec['time']
    with open(f'{d}/first70.csv','w') as f:
        f.write('time_s,temperature_C,displacement_mm\n')
        for i in range(h0): f.write(f'{t[i]:.6f},{T[i]:.9g},{y[i]:.9g}\n')
    with open(f'{d}/full.csv','w') as f:
        f.write('time_s,temperature_C,displacement_mm\n')
        for i in range(len(t)): f.write(f'{t[i]:.6f},{T[i]:.9g},{y[i]:.9g}\n')
    res={'name':n}
    for model in sys.argv[3].split(','):
        o=f'{d}/fit_{model}'
        r=subprocess.run(['/work/venv/bin/smafl','fit',f'{d}/first70.csv','--model',model,'--out',o],capture_output=True,text=True)
        if r.returncode: res[model]=r.stderr[-300:]; continue
        m=sj.load_model(f'{o}/fit.json')
        pred=np.asarray(sj.simulate(m, T, float(t[1]-t[0])))
        res[model]={'train_x':float(np.sqrt(np.mean((pred[:h0]-y[:h0])**2))/sd),'held_x':float(np.sqrt(np.mean((pred[h0:]-y[h0:])**2))/sd)}
    print(res, flush=True); out.write(json.dumps(res)+'\n'); out.flush()
