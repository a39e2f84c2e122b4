"""Table of wholefit.py ALL outputs: python whole_table.py FILE.all.txt ..."""
import re, sys
from smafl_jax.effects import EFFECTS
print("| record | whole-record base / noise | first | second | truth gain (rank) | truth first or in the first's lookalikes |")
print("|---|---|---|---|---|---|")
for f in sys.argv[1:]:
    txt = open(f).read().splitlines()
    head = txt[0].split()
    truth, seed, base = head[0], head[1], float(re.search(r"whole-record ([\d.]+)x", txt[0]).group(1))
    rk = [(x.rsplit(" ", 1)[0], float(x.rsplit(" ", 1)[1])) for x in txt[-1][len("ranked: "):].split(", ")]
    names = [n for n, _ in rk]
    tg = dict(rk).get(truth)
    first = names[0]
    # lookalike: the first and the truth share a lookalike group (`AbstractEffect.lookalikes`)
    lk = truth in EFFECTS and first in EFFECTS and bool(set(EFFECTS[first].lookalikes) & set(EFFECTS[truth].lookalikes))
    ok = "-" if truth == "none" else ("yes" if first == truth else ("lookalike" if lk else "no"))
    tr = "-" if tg is None else f"{tg:+.3f} ({names.index(truth) + 1})"
    print(f"| {truth} {seed} | {base:.2f} | {rk[0][0]} {rk[0][1]:+.3f} | {rk[1][0]} {rk[1][1]:+.3f} | {tr} | {ok} |")
