"""Session 73: diagnosis-style start screening (training loss, first 70 %) of plant-B grid records; sign vs the truth."""
import sys, time
sys.path.insert(0, "experiments")
import numpy as np
import indep_plant_b as pb
import fit_plant_b as fb
import smafl_jax as sj
from smafl_jax.diagnosis import _diagnose as D
from smafl_jax.identify._choose import screen_start
from smafl_jax.models._hysteresis import hysteresis_of
seeds = [int(s) for s in sys.argv[1:]]
for c in fb.grid(seeds, 10.0)[: 12 * len(seeds)]:
    kw = {k: v for k, v in c.items() if k != "seed"}
    r = pb.make_record(c["seed"], **kw)
    h0 = r["heldout_start"]
    rec = sj.Record.from_arrays(r["time"][:h0], r["voltage"][:h0], np.round(r["output"][:h0], 4), input_name="voltage_V", output_name="displacement_mm")
    base0, _ = D.choose_base(rec)
    w = np.ones(h0)
    t = time.time()
    model, table, info = screen_start(base0, [(rec.u, rec.y, rec.dt)], [w], val_weights=None, memory="rule")
    th = model.thermal
    truth = 1 if c["sensor"] == "displacement" else -1
    o = hysteresis_of(model).orientation
    print(f"{fb.name_of(c)} truth {truth:+d} chosen {o:+d} {'ok' if o == truth else 'WRONG'} sees {model.sees} "
          f"u0 {float(th.u0) if th.u0 is not None else float('nan'):.4g} loss {min(x['loss'] for x in table if x.get('loss') is not None):.6g} "
          f"{time.time() - t:.1f} s", flush=True)
