"""Session 27: mean and RMS error (noise SD units, 0.005 mm) in 20 time blocks of e_SEED.npy from probe_cell.py."""
import numpy as np, sys
d = np.load(sys.argv[1]); t,u,y,yh = d.T; e = yh-y; n=len(t); h0=int(0.7*n)
sd=0.005
for a in range(0, n, n//20):
    b=a+n//20; print(f"{t[a]:7.0f}-{t[min(b,n-1)]:5.0f} u mean {u[a:b].mean():.2f} y {y[a:b].mean():.3f} err mean {e[a:b].mean()/sd:7.2f} rms {np.sqrt(np.mean(e[a:b]**2))/sd:6.2f}")
