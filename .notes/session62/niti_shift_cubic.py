import numpy as np, glob
fs=sorted(glob.glob('/work/shared/data/real/niti_wire_electric_*.csv'))
R=[]
for f in fs:
    d=np.genfromtxt(f,delimiter=',',names=True); R.append((d['temperature_front_C'],d['length_signal'],d['temperature_end_C']))
def lag(T,a):
    x=np.empty_like(T); s=T[0]
    for i,v in enumerate(T): s=s+a*(v-s); x[i]=s
    return x
def shift(x,k):
    if k==0: return x
    return np.r_[x[k:], np.full(k,x[-1])] if k>0 else np.r_[np.full(-k,x[0]), x[:k]]
for k in [-10,-5,-3,-1,0,1,3,5,10]:
    res=[]
    for t in range(5):
        tr=[j for j in range(5) if j!=t]
        X=np.concatenate([shift(R[j][0],k) for j in tr]); Y=np.concatenate([R[j][1] for j in tr])
        lo,hi=X.min(),X.max(); c=np.polyfit(X,Y,3)
        res.append(np.sqrt(np.mean((np.polyval(c,np.clip(shift(R[t][0],k),lo,hi))-R[t][1])**2)))
    print('shift',k, np.round(res,2), 'gm %.3f'%np.exp(np.mean(np.log(res))))
