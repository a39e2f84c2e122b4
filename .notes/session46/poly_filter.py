# LORO of a static cubic on the front thermocouple, raw vs first-order-filtered (lag tau) or lead-lag, per record.
import numpy as np, glob
fs = sorted(glob.glob("/work/shared/data/real/niti_wire_*.csv"))
D = [np.genfromtxt(f, delimiter=",", names=True) for f in fs]
def filt(x, dt, lead, tau):
    # zoh lag tau of x, lead-lag: x' = z + g (x - z)
    if tau <= 0: return x
    b = np.exp(-dt / tau); z = np.empty_like(x); z[0] = x[0]
    for k in range(1, len(x)): z[k] = b * z[k-1] + (1 - b) * x[k-1]
    g = np.expm1(dt / tau) / np.expm1(dt / lead) if lead > 0 else 0.0
    return z + g * (x - z)
def loro(lead, tau, deg=3):
    X = [filt(d["temperature_front_C"], 0.1, lead, tau) for d in D]; Y = [d["length_signal"] for d in D]
    out = []
    for i in range(len(D)):
        xt = np.concatenate([X[j] for j in range(len(D)) if j != i]); yt = np.concatenate([Y[j] for j in range(len(D)) if j != i])
        c = np.polyfit(xt, yt, deg); out.append(np.sqrt(np.mean((np.polyval(c, X[i]) - Y[i])**2)))
    return np.array(out)
base = loro(0, 0)
print("raw", np.round(base, 3))
for lead, tau in [(0, 0.3), (0, 1), (0, 3), (1, 0.3), (3, 0.5), (5, 1), (10, 2)]:
    r = loro(lead, tau); print(lead, tau, np.round(r / base, 3), "median", round(float(np.median(r / base)), 3))
