import sys, os, numpy as np, json
sys.path.insert(0, "/work/main/experiments")
import indep_plant_c as pc
import plant_c_trial as T
base = T.RECORDS["r10"]
_, _, meta, _ = (lambda a: (None, None, pc.make_record(*a)[4], None))(base)
for new in ["r10c", "r10d"]:
    os.environ["PLANT_C_OFFSET"] = repr(meta["offset_mm"])
    t, u, meas, clean, m = pc.make_record(*T.NEW_RUNS[new][1])
    os.environ.pop("PLANT_C_OFFSET")
    sd = m["noise_sd"]
    for st in sys.argv[1:]:
        f = f"/tmp/s45/{new}_{st}.csv"
        d = np.genfromtxt(f, delimiter=",", names=True)
        y = d[[n for n in d.dtype.names if n.endswith("_model")][0]]
        e = (y - clean) / sd
        seg = np.array_split(np.arange(len(e)), 10)
        print(new, st, "rmse/sd %.1f" % np.sqrt(np.mean(e**2)), "per10%:", [round(float(np.sqrt(np.mean(e[s]**2))), 1) for s in seg], 'u first', u[:3], 'clean0', clean[:2])
