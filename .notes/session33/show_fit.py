import json, sys
for tag in sys.argv[1:]:
  for root in ("/tmp/s32/multi/o_","/tmp/s33/multi/o_"):
    try: d=json.load(open(root+tag+"/fit.json"))
    except FileNotFoundError: continue
    m=d["metrics"]; th=d["model"].get("thermal") or d["model"].get("base",{}).get("thermal") or {}
    print(root.split('/')[2], tag, d["settings"]["structure"], "train x %.3f" % m["noise"]["train_ratio"], "loro x %.3f" % m["noise"]["validation_ratio"] if m["noise"].get("validation_ratio") else "", "k1", th.get("k1"), "solver s %.0f total %.0f" % (d["solver"]["seconds"], d["solver"]["total_seconds_with_folds"]))
    for f in d["validation"]["folds"]:
        hs=f.get("heldout_start") or {}
        sw=hs.get("shared_start_whole")
        print("    fold", f["record"], "model rmse %.4f" % f["model"]["rmse"], "(whole, trained start %.4f)" % sw["rmse"] if sw else "", hs.get("thermal"), hs.get("memory"), {k: round(v["rmse"],4) for k,v in f["baselines"].items()})
    for r in d.get("per_record_start") or []: print("    start", r)
    for n in d["notes"]:
        if "start" in n and "record" in n: print("    note:", n[:200])
