"""Replay: the ranking's base lowered to a candidate fitted at strength 0 (all effect parameters <= 1e-8), answers before/after."""
import sys, io, contextlib, copy
sys.path.insert(0, ".notes/session67")
with contextlib.redirect_stdout(io.StringIO()):
    import tally as T
import smafl_jax.diagnosis._naming as N
N.WHOLE_BASE_MAX = 5.0
changed = 0
for key, r in sorted(T.recs.items()):
    nm = r.get("naming")
    if not nm or not nm.get("ranking"):
        continue
    null = [x for x in nm["ranking"] if x["parameters"] and all(abs(v) <= 1e-8 for v in x["parameters"].values())]
    rb = nm["base_rmse"]
    rb2 = min([rb] + [x["rmse"] for x in null])
    s1, a1 = T.answer(r, 5.0)
    if rb2 < rb * (1 - 1e-6):
        r2 = copy.deepcopy(r)
        n2 = r2["naming"]
        n2["base_rmse"] = rb2
        for x in n2["ranking"]:
            x["gain"] = 1 - x["rmse"] / rb2
        n2["ranking"].sort(key=lambda x: -x["gain"])
        s2, a2 = T.answer(r2, 5.0)
        print(key, f"base {rb:.4g} -> {rb2:.4g}", s1, "->", s2, "ok" if T.ok(key[0], s2, a2) else "--")
        changed += (s1 != s2)
print("changed answers:", changed)
