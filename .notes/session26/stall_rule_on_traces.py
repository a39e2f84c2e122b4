import json, math, sys
def solves(f):
    t=json.load(open(f)); out=[]
    for r in t:
        if r['num_steps']==0: out.append([])
        out[-1].append(r['loss_last_accepted_step'])
    return out
for f, ns in (("/tmp/s26/trace_G.json",(4200,21000,6000,30000)),("/tmp/s26/trace_C.json",(4200,4200,21000,6000,30000))):
    for W,tau in ((20,0.1),(20,0.05),(20,0.02),(20,0.01),(40,0.02)):
        row=[]
        for L,n in zip(solves(f),ns):
            stop=len(L)-1
            for k in range(W+1,len(L)):
                if L[k-W]>0 and n/2*math.log(L[k-W]/L[k])<tau: stop=k;break
            lost=n/2*math.log(L[stop]/L[-1]) if L[-1]>0 else 0
            row.append(f"{stop+1}/{len(L)} lost {lost:.2f}")
        print(f.split('_')[-1], W, tau, row)
