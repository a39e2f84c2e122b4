"""Session 73: the newest run of each blind record (seeds 10-14 + clean 39-48), shared by tally.py, floor_split.py and
contradicted.py: the session-70 answer (tally_auto), replaced by runs under the bound rule (session 72 bound_retry,
then the folders given)."""
import io, contextlib, sys
sys.path.insert(0, ".notes/session70")
sys.path.insert(0, ".notes/session67")
from paired import rows, answer, ok  # noqa: E402,F401

with contextlib.redirect_stdout(io.StringIO()):
    import tally_auto as ta  # noqa: E402  (prints its own table on import)

TRUTHS = ta.TRUTHS


def newest(extra_dirs):
    """Yield ``(truth, seed, row, (selected, ambiguous), source)`` per record; source "rule", "auto" or "time"."""
    newer = {}
    for d in ["experiments/results/diagnose_independent_session72/bound_retry", *extra_dirs]:
        newer.update(rows(d))
    for (truth, seed), r in sorted(ta.old.items()):
        s_ = seed - 1000 * TRUTHS.index(truth)
        if not (10 <= s_ <= 14 or (truth == "none" and 39 <= s_ <= 48)):
            continue
        if (truth, seed) in newer:
            r = newer[(truth, seed)]
            yield truth, s_, r, answer(r, 5.0), "rule"
        elif (truth, seed) in ta.auto:
            r = ta.auto[(truth, seed)]
            yield truth, s_, r, answer(r, 5.0), "auto"
        else:
            yield truth, s_, r, ta.floor.get((truth, seed)) or answer(r, 5.0), "time"
