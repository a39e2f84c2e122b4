"""Rows of diagnose_independent JSONs with the whole-record naming: gates-only selection vs named.
python naming_table.py DIR [DIR ...]"""
import glob, json, sys, collections, os, tempfile
sys.path.insert(0, "experiments")
import indep_effects as ie
import smafl_jax as sj
from smafl_jax.diagnosis import rename
from smafl_jax.identify._metrics import noise_floor


def noise_sd(truth, seed):
    with tempfile.TemporaryDirectory() as tmp:
        s = seed - 1000 * ie.ALL_TRUTHS.index(truth)
        path, _ = ie.write_effect_record(tmp, truth, seed)
        return noise_floor([sj.load_record(path)])["sd"]
t = collections.Counter()
for d in sys.argv[1:]:
    for f in sorted(glob.glob(f"{d}/*.json")):
        if f.endswith(".partial.json"):
            continue
        for r in json.load(open(f))["rows"]:
            nm = r.get("naming")
            truth, sel, amb = r["truth"], r["selected_new"], r["ambiguous_new"] or []
            if nm:  # replay the current decision (`rename`) on the stored ranking (runs made before its last change)
                (sel, amb), _ = rename(nm, nm["split_selected"], nm["split_ambiguous"], min_gain=0.05, noise_sd=noise_sd(truth, r["case"]["requested_seed"]))
            gates = nm["split_selected"] if nm else sel
            gamb = nm["split_ambiguous"] if nm else amb
            ok = (lambda s, a: not s) if truth == "none" else (lambda s, a: bool(s) and (truth in s or truth in a))
            rk = ", ".join(f"{x['name']} {x['gain']:+.3f}" for x in nm["ranking"][:3]) if nm else ""
            print(f"{truth:20s} {r['case']['requested_seed']:5d} base {r['base_train_over_noise']:.2f}/{r['base_heldout_over_noise']:.2f}  gates {'+'.join(gates) or 'none':28s} {'ok' if ok(gates, gamb) else '--'}  named {'+'.join(sel) or 'none':20s} {','.join(amb):30s} {'ok' if ok(sel, amb) else '--'}  {rk}  [{nm and nm.get('base')} {nm and nm.get('base_over_noise') and round(nm['base_over_noise'], 2)} {nm and nm.get('applied')}]")
            k = "clean" if truth == "none" else "effect"
            t[k] += 1; t[k + " gates ok"] += ok(gates, gamb); t[k + " named ok"] += ok(sel, amb)
            if truth != "none":
                t["effect gates wrong"] += bool(gates) and not ok(gates, gamb); t["effect named wrong"] += bool(sel) and not ok(sel, amb)
print(dict(t))
