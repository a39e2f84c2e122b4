import sys, json, glob
for f in sys.argv[1:]:
    for r in json.load(open(f))["rows"]:
        cands = sorted([c for c in r["candidates"] if c.get("heldout_gain") is not None], key=lambda c: -c["heldout_gain"])
        print(r["truth"], r["case"]["requested_seed"], "base held %.2fx train %.2fx" % (r["base_heldout_over_noise"], r["base_train_over_noise"]))
        for c in cands[:5]:
            print(f"   {c['name']:20s} held {c['heldout_gain']:+.3f}  {str(c.get('decision',''))[:150]}")
        nm = r.get("naming") or {}
        if nm.get("ranking"): print("   ranking:", ", ".join(f"{x['name']} {x['gain']:+.3f}" for x in nm["ranking"][:5]), "split_selected", nm.get("split_selected"))
        for w in r["warnings"]: print("   W:", w[:200])
