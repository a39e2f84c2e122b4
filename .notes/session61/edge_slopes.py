"""Slope of each family's joint model at the ends of its trained range, against its mean slope (saturation check)."""
import numpy as np
import smafl_jax as sj
D = "/work/shared/data/real/"
FAM = {"electric": ([f"niti_wire_electric_0{i}.csv" for i in range(1, 6)], dict(input="temperature_front_C", output="length_signal")),
       "water": ([f"niti_wire_water_step_0{i}.csv" for i in range(1, 5)], dict(input="temperature_front_C", output="length_signal")),
       "cavatappi": ([f"cavatappi_pneumatic_200g_{s}.csv" for s in ("s1_t1", "s1_t2", "s2_t1", "s3_t1")], dict(input="pressure", output="displacement_mm", resample=0.01))}
for fam, (names, kw) in FAM.items():
    recs = [sj.load_record(D + n, **kw) for n in names]
    for k in range(len(recs)):
        train = [r for j, r in enumerate(recs) if j != k]
        model, doc, _ = sj.fit_records(train, split="none", hold_input="off")
        lo = min(r.u.min() for r in train); hi = max(r.u.max() for r in train)
        n = 2000; up = np.linspace(lo, hi, n); x = np.concatenate([up[::-1], up, up[::-1]])  # descend, ascend, descend
        y = np.asarray(sj.simulate(model, x))
        asc, desc = y[n:2 * n], y[2 * n:][::-1]
        mean = abs(asc[-1] - asc[0]) / (hi - lo)
        e = n // 10
        top = abs(asc[-1] - asc[-e]) / (up[-1] - up[-e]) / mean
        bot = abs(desc[e] - desc[0]) / (up[e] - up[0]) / mean
        print(f"{fam} without {names[k][-10:-4]}: slope at top {top:.2f}, at bottom {bot:.2f} (x mean slope)", flush=True)
