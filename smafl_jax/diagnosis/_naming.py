"""Which effect, once the split gates say that one is there: the whole-record ranking (issue 13).

The calibrated gates of `diagnose` (held-out gain, folds, null records) decide *whether* the base model misses an
effect.  Which catalogue effect it is, they decide poorly on records from an independent plant: the base fitted on
70 % of a record often absorbs the effect there (26 of 72 stored effect records train within 1.15x the noise) and
the candidates then compete on extrapolation to the held-out block, where the effect's own parameters are weakly
determined.  Fitted on every sample, the true effect ranked first on 12 of 21 stored effect records against 6 of
21 named by the split rule (session 65, `.notes/session65/`), while the whole-record gain alone is no detector (a
clean record with a misspecified base gains 28-73 % on whichever effect).  So: the gates decide whether, the
whole record decides which, and an effect that does not lower the whole-record RMSE by ``min_gain`` is not named.
Measured on fresh independent records (seeds 10-13, session 66): the truth named on 16 of 32 against 10 by the gates
alone, wrong names 10 -> 6, clean records 8/8 (7/8); experiments/results/diagnose_independent_session66/.  With the
guard at 5x (session 67) and fresh seed 14: 5 of 8 right, none wrong, clean 2/2; seeds 10-14: 24 of 40, clean 10/10
(experiments/results/diagnose_independent_session67/).
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from .._progress import LOGGER as PROGRESS
from .._progress import Steps
from ..effects import ExtendedModel
from ..identify._metrics import NOISE_FLOOR_WARN
from ..models._hysteresis import thermal_of
from ._diagnose import (
    Split,
    _effect_params,
    _log,
    fit_extended,
    lookalike_groups,
    refine_model,
    score,
    whole_record_split,
)

#: the ranking names an effect only when the whole-record base is within this multiple of the output's noise SD
#: (estimated from the data): a base that misses much more than the effect gains on whichever effect (an independent
#: asymmetric-cooling record, base 22x the noise: creep +42 %, the true effect +22 %); there the gates' choice stands.
#: 2x (`NOISE_FLOOR_WARN`) in session 66; 5x since session 67: between 2x and 5x the ranking's leader was the truth on
#: all 6 effect records of seeds 10-13 where the gates accepted something (the gates on 4), e.g. output_lag s8012,
#: base 3.6x, +71 %, where the gates named rate_dependence; the catalogue's effects are tested at >= 5x the noise
WHOLE_BASE_MAX = 5.0

#: where the gates are not run (a base at the noise floor on the held-out block) the whole-record gain must reach at
#: least this even when ``min_gain`` is lower, and the named candidate must not hold out worse than the base
FLOOR_MIN_GAIN = 0.05
#: ... and the whole-record base must be within this multiple of the noise SD (no calibrated gate stands behind that
#: name, so the session-66 bound stays there)
FLOOR_BASE_MAX = NOISE_FLOOR_WARN

#: a candidate's base part replaces the ranking's base only when lower than it by more than this relative amount
BASE_PART_RTOL = 1e-6

#: a lookalike of the named effect that reaches this share of its whole-record RMSE reduction is reported with it as an
#: ambiguous set (the data do not separate them).  A share of the gain, not a tolerance on the RMSE: at a 5 % gain a
#: 10 % RMSE tolerance (the gates' own) took in every lookalike (8 effects on independent resistance_tc s1012)
WHOLE_LOOKALIKE_SHARE = 0.9


def whole_record_ranking(record, base, names, *, refine=True, verbose=False) -> dict:
    """The base and each effect in ``names`` refitted on every sample of ``record`` (variable projection, then the
    symmetric refinement, as on the split), ranked by training-RMSE gain over the refitted base, or over a candidate's
    base part (its effect taken out) where that is lower: the gain is then the effect's, not the optimiser's.

    ``base`` is the diagnosis's fitted base (an `ExtendedModel` with no effect); every candidate starts from the
    refitted base, so none gets a better start than the base it is compared with.  ``refine``: the symmetric
    refinement as in the diagnosis (False: variable projection only, as `diagnose(refine=False)` fits the candidates).
    """
    t0 = time.time()
    w = whole_record_split(record)
    # test = train: `refine_model` keeps a refinement only if it does not raise the error on `split.test`; with no
    # held-out part that is the training error, which the refinement lowers by construction
    full = Split(w.kind, w.rule, w.train, w.train, w.train_labels, w.train_labels)
    fin = (lambda m: refine_model(m, full)) if refine else (lambda m: m)
    bases = {"split choice": fin(fit_extended(base, [], full)[0])}
    th = thermal_of(base)
    if th is not None and hasattr(th, "lag") and hasattr(base.base, "thermal"):
        # the drive's sampling lag (0 or 1 sample) is chosen on the split's held-out block, which a base far from it
        # predicts badly; on every sample the two lags have the same parameters, so the lower RMSE decides (a clean
        # independent record at 4.5 Hz: 1.39x the noise with the split's lag, 1.01x with the other; every timing
        # effect then gained 26-28 % on it)
        other = ExtendedModel(dataclasses.replace(base.base, thermal=dataclasses.replace(th, lag=1 - th.lag)), ())
        bases[f"lag {1 - th.lag}"] = fin(fit_extended(other, [], full)[0])
    base_rmse = {k: score(m, full.train)[0]["rmse"] for k, m in bases.items()}
    chosen = min(base_rmse, key=lambda k: base_rmse[k] if np.isfinite(base_rmse[k]) else np.inf)
    b, rb = bases[chosen], base_rmse[chosen]
    rows = []
    steps = Steps("diagnose: naming on the whole record", len(names), unit="effects")
    for n in names:
        PROGRESS.info(f"  diagnose: whole-record fit of {n}")
        c = fin(fit_extended(b, [n], full)[0])
        rc = score(c, full.train)[0]["rmse"]
        # the candidate's base part alone (its effect taken out) is a base model too: a refinement that ends better
        # with the effect switched off (a clean plant-A record, s311: four effects at strength 0 each "gained" 8.3 %)
        # found a better base, not an effect
        rp = score(ExtendedModel(c.base, ()), full.train)[0]["rmse"]
        rows.append({"name": n, "rmse": rc, "parameters": _effect_params(c.get(n)), "base_part_rmse": rp})
        steps.advance(note=f"{n}: {100 * (1.0 - rc / rb) if rb > 0 and np.isfinite(rc) else 0.0:+.1f} %")
    chosen, rb = rebase_ranking(rows, base_rmse, chosen)
    rows.sort(key=lambda r: -r["gain"])
    _log("whole-record ranking: " + ", ".join(f"{r['name']} {100 * r['gain']:+.1f} %" for r in rows), verbose)
    return {"base_rmse": rb, "base_rmse_by_start": base_rmse, "base": chosen, "ranking": rows, "seconds": time.time() - t0}


def rebase_ranking(rows, base_rmse, chosen) -> tuple[str, float]:
    """``(chosen, base RMSE)`` of a ranking: the base ``chosen`` in ``base_rmse`` ({start: RMSE}), or the lowest
    ``base_part_rmse`` of the candidate ``rows`` where that is lower by more than `BASE_PART_RTOL` (added to
    ``base_rmse``); every row's ``gain`` is then set against it."""
    rb = base_rmse[chosen]
    # lower by more than rounding: a base part equal to the base (a delay fitted at 0) leaves the base named as it was
    parts = [r for r in rows if np.isfinite(r["base_part_rmse"]) and r["base_part_rmse"] < (1.0 - BASE_PART_RTOL) * rb]
    if parts:
        best = min(parts, key=lambda r: r["base_part_rmse"])
        chosen, rb = f"base part of the {best['name']} fit", best["base_part_rmse"]
        base_rmse[chosen] = rb
    for r in rows:
        r["gain"] = 1.0 - r["rmse"] / rb if rb > 0 and np.isfinite(r["rmse"]) else 0.0
    return chosen, rb


def whole_record_name(ranking, min_gain, share=WHOLE_LOOKALIKE_SHARE) -> tuple[str | None, list[str]]:
    """``(name, ambiguous)`` from a `whole_record_ranking`: the first effect, or None when it lowers the whole-record
    RMSE by less than ``min_gain``; its lookalikes (`lookalike_groups`) that reach ``share`` of its gain form the
    ambiguous set (empty, or the name and those lookalikes)."""
    rows = ranking["ranking"]
    if not rows or rows[0]["gain"] < min_gain:
        return None, []
    first = rows[0]
    amb = [r["name"] for r in rows[1:] if lookalike_groups([first["name"], r["name"]]) and r["gain"] >= share * first["gain"]]
    return first["name"], ([first["name"], *amb] if amb else [])


def describe_rule(min_gain, share=WHOLE_LOOKALIKE_SHARE) -> str:
    return (
        "when the gates accept an effect, or cannot be run because the base holds out at the noise floor, the name is "
        "chosen on the whole record: the base (drive lag re-chosen) and "
        "every fitted candidate are refitted on every sample and the candidate with the largest training-RMSE gain is "
        f"named if that gain is >= {100 * min_gain:g} % (else nothing is selected); its lookalikes reaching "
        f"{100 * share:g} % of its gain are reported as ambiguous with it; when the whole-record base stays above "
        f"{WHOLE_BASE_MAX:g}x the output's noise SD the gates' choice stands (where the gates were not run, above "
        f"{FLOOR_BASE_MAX:g}x nothing is named)"
    )


def name_on_whole_record(
    record, base, names, selected, ambiguous, *, min_gain, noise_sd, heldout_gain=None, refine=True, verbose=False
):
    """``(doc, (selected, ambiguous), warning)``: the gates' ``selected`` / ``ambiguous`` renamed by the whole-record
    ranking of ``names`` (`whole_record_ranking`, `whole_record_name`), kept when the whole-record base is above
    ``WHOLE_BASE_MAX`` times ``noise_sd``; ``warning`` (or None) says when the ranking dropped the selection, or named
    one where the gates were not run (``selected`` empty: a base at the noise floor on the held-out block)."""
    doc = whole_record_ranking(record, base, names, refine=refine, verbose=verbose)
    return (doc, *rename(doc, selected, ambiguous, min_gain=min_gain, noise_sd=noise_sd, heldout_gain=heldout_gain))


def rename(doc, selected, ambiguous, *, min_gain, noise_sd, heldout_gain=None):
    """The decision of `name_on_whole_record` on a ranking ``doc`` (updated in place): ``((selected, ambiguous),
    warning)``.  ``selected`` empty: the base held out at the noise floor and the gates were not run; the ranking
    alone then names an effect (the same base guard, a gain of at least ``max(min_gain, FLOOR_MIN_GAIN)``, and the
    candidate's split held-out gain, from ``heldout_gain`` by name, not negative), and the warning says so."""
    ratio = doc["base_rmse"] / noise_sd if noise_sd and noise_sd > 0 else None
    doc.update(split_selected=list(selected), split_ambiguous=list(ambiguous), base_over_noise=ratio)
    bound = WHOLE_BASE_MAX if selected else FLOOR_BASE_MAX
    if ratio is None or ratio > bound:
        doc.update(applied=False, named=selected[0] if selected else None, ambiguous=list(ambiguous))
        doc["reason"] = (
            "no noise estimate"
            if ratio is None
            else f"the whole-record base stays at {ratio:.3g}x the noise SD (> {bound:g}x): misfit that any "
            "effect absorbs, so the ranking does not name one" + ("; the gates' choice stands" if selected else "")
        )
        return (list(selected), list(ambiguous)), None
    name, amb = whole_record_name(doc, min_gain if selected else max(min_gain, FLOOR_MIN_GAIN))
    held = (heldout_gain or {}).get(name)
    if not selected and name is not None and held is not None and held < 0.0:
        doc["reason"] = f"{name} leads on the whole record but holds out {100 * held:+.1f} % against the base: not named"
        name, amb = None, []
    doc.update(applied=True, named=name, ambiguous=amb)
    best = doc["ranking"][0] if doc["ranking"] else None
    if name is None:
        if not selected:
            return ([], []), None
        warning = (
            f"the calibrated gates accepted {selected[0]}, but refitted on every sample no effect lowers the RMSE by "
            f">= {100 * min_gain:g} %"
            + (f" (best {best['name']}, {100 * best['gain']:+.1f} %)" if best else "")
            + "; nothing selected (diagnosis.json 'naming')"
        )
        return ([], []), warning
    if not selected:
        warning = (
            f"{name} named on the whole record only: the base (or smafl fit's default model, see base.reference_fit) "
            f"holds out at the noise floor, where no held-out gate stands behind a name, but refitted on every sample "
            f"{name} lowers the RMSE by {100 * best['gain']:.1f} % (base "
            f"{ratio:.3g}x the noise SD); the held-out figures cannot confirm it (diagnosis.json 'naming')"
        )
        return ([name], amb), warning
    if name != selected[0]:
        if held is None or held >= 0.0:
            return ([name], amb), None
        # kept: on 4 such independent effect records of seeds 10-14 the name was the truth 3 times (creep s6012, delay
        # s7012, output_lag s8011; creep on resistance_tc s1012), the split's block judging extrapolation there.  But the
        # report's held-out figures then read as a step back (clean plant-A s301, session 68), so the user is told why
        gates_held = (heldout_gain or {}).get(selected[0])
        warning = (
            f"{name} named on the whole record ({100 * best['gain']:+.1f} % RMSE, the largest gain), although on the "
            f"split it holds out {100 * held:+.1f} % against the base"
            + (f" ({selected[0]}, which the gates accepted, {100 * gates_held:+.1f} %)" if gates_held is not None else "")
            + ": the held-out figures of this report are worse than the base's; treat the name as uncertain "
            "(diagnosis.json 'naming')"
        )
        return ([name], amb), warning
    return (list(selected), list(dict.fromkeys([*ambiguous, *amb]))), None


def naming_decisions(candidates, doc) -> None:
    """Rewrite the decisions of the candidates the whole-record naming concerns (after `_decisions`), so that a
    report says why a candidate the gates accepted is not named, or why one they rejected is."""
    gain = {r["name"]: r["gain"] for r in doc["ranking"]}
    split_first, name = (doc["split_selected"] or [None])[0], doc["named"]
    for c in candidates:
        n = c["name"]
        if split_first is None and name is not None and n == name:
            c["decision"] = (
                f"selected: named on the whole record ({100 * gain[n]:+.1f} % RMSE, the largest gain); the base (or smafl "
                "fit's default model) held out at the noise floor, where no held-out gate stands behind a name"
            )
        elif split_first is None:
            pass
        elif name is None and n == split_first:
            best = doc["ranking"][0]
            c["decision"] = (
                f"passes the gates; not selected: refitted on every sample no effect lowers the RMSE by the minimum gain "
                f"(best {best['name']} {100 * best['gain']:+.1f} %, {n} {100 * gain.get(n, 0.0):+.1f} %)"
            )
        elif name is not None and name != split_first and n == name:
            c["decision"] = (
                f"selected: named on the whole record ({100 * gain[n]:+.1f} % RMSE, the largest gain; {split_first}, which "
                f"the gates accepted, {100 * gain.get(split_first, 0.0):+.1f} %)"
            )
        elif name is not None and name != split_first and n == split_first:
            c["decision"] = (
                f"passes the gates; not selected: refitted on every sample {name} explains more "
                f"({100 * gain[name]:+.1f} % vs {100 * gain.get(n, 0.0):+.1f} % RMSE)"
            )
        if n in gain:
            c["whole_record_gain"] = gain[n]
