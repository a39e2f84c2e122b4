"""Session 73: the diagnosis-style start screening of blind records (chosen orientation, input, thermal start, best loss).
Run from a checkout (or a snapshot on PYTHONPATH): python .notes/session73/screen_replay.py none:45 nonlinear_cooling:4014 ..."""
import sys, time, tempfile
sys.path.insert(0, "experiments")
import indep_effects as ie
import smafl_jax as sj
from smafl_jax.diagnosis import _diagnose as D
from smafl_jax.identify._choose import screen_start
from smafl_jax.models._hysteresis import hysteresis_of
for item in sys.argv[1:]:
    truth, seed = item.split(":")
    with tempfile.TemporaryDirectory() as tmp:
        path, case = ie.write_effect_record(tmp, truth, int(seed))
        rec = sj.load_record(path)
    base0, _ = D.choose_base(rec)
    split = D.make_split(rec, kind="auto")
    data = [(s.u, s.y, s.dt) for s in split.train]
    weights = [s.mask.astype(float) for s in split.train]
    t = time.time()
    model, table, info = screen_start(base0, data, weights, val_weights=None, memory="rule")
    th = getattr(model, "thermal", None)
    loss = min(r["loss"] for r in table if r.get("loss") is not None)
    print(f"{truth} {seed} orient {hysteresis_of(model).orientation:+d} sees {getattr(model, 'sees', None)} "
          f"start {th.init if th else None} u0 {float(th.u0) if th is not None and th.u0 is not None else float('nan'):.4g} "
          f"best-row loss {loss:.6g} n_rows {len(table)} {time.time() - t:.1f} s", flush=True)
