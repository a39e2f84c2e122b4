"""The saved model's input held to its trained range (``fit_record(hold_input=...)``, ``smafl fit --hold-input``).

Outside the range a model was fitted on, its play operators and polynomial extrapolate without a physical meaning, and
a hysteresis keeps the memory of the excursion for good.  Measured (session 61):

- measured inputs on real rigs, each run predicted by the joint fit of the other runs of its family: held, the NiTi
  electric run whose thermocouple spiked to 220 C went 18.2 -> 3.9 and the water run that went down to -2.6 C (the
  others stayed above 23.6 C) 9.2 -> 1.2 length units; the other 7 NiTi runs and the 4 pneumatic cavatappi runs
  stayed within 1 % (held out / static cubic, gm: electric 1.087 -> 0.798, water 1.313 -> 0.789);
- a drive voltage's thermal state on independent simulated plants, held to its trained range: worse. Plant A, six
  records with one stretch above the trained voltage (held out / noise): 35 -> 112, 35 -> 340, 47 -> 340, 16 -> 27,
  111 -> 368, 12 -> 49 (also after the stretch, back in range: 55 -> 421 on one); plant B seed 39, 7 records: gm
  14.8 -> 20.4 (three worse, one better: 67 -> 11).

A hotter thermal state from a stronger drive is a state the plant really reaches, and its response goes on; a measured
temperature beyond the trained range was there a sensor glitch or a wire past its transformation, but a pneumatic
muscle goes on extending with pressure (cavatappi s2_t1's validation block, beyond its training pressures: 0.38
extrapolating, 1.17 held).  So ``"auto"`` holds a model whose hysteresis sees the measured input directly, unless the
held-out samples that leave the training range (a one-record fit's validation samples, a joint fit's
leave-one-record-out folds) are predicted better extrapolating (`hold_choice`).

A cascade's thermal state is held on its cold side only (session 62).  Held out on 63 plant-B fits (post-hoc; 24 of
them fresh seeds 40-41), holding below changed 6: four better (469 -> 58, 130 -> 9.3, 8.35 -> 7.14, 1.20 -> 1.08 x the
noise; the first two: a warm-looking fitted start, then the first long cooling below anything the training part cooled
to, where the play operators and the cubic ran off by 1.8 spans of the output) and two worse (1.06 -> 1.88, and 360 ->
455 on a record whose training part never cooled at all); gm 4.61 -> 4.31.  Holding above made 13 of the first 39
worse (all 63: gm 6.75).  15 fresh plant-A cells: no change (their held-out parts stay in range).  An SMA colder than
its trained range mostly sits below its transformation; hotter, it goes on transforming.
"""

from __future__ import annotations

from typing import Any

from .._choices import HOLD_INPUT
from .._errors import UserInputError
from ..models._hysteresis import hysteresis_of, thermal_of

#: fit.json ``settings.hold_input.why`` of a cascade held by "auto".
COLD_SIDE = (
    "the cascade's thermal state is held at the low edge of its trained range: colder than the training part ever was, "
    "the model does not extrapolate (an SMA below its transformation stays put); hotter, it extrapolates, as the plant "
    "goes on responding to a stronger drive (hold_input on holds both sides)"
)


def check_hold_input(rule: str) -> str:
    """``rule`` if it is one of `HOLD_INPUT`, else a `UserInputError` naming them."""
    if rule not in HOLD_INPUT:
        raise UserInputError(f"unknown hold_input {rule!r}; choose one of {HOLD_INPUT}")
    return rule


def hold_fitted(model: Any, doc: dict, rule: str = "auto") -> Any:
    """``model`` with its hysteresis holding its input to the trained range in ``doc["data"]`` by ``rule``
    (`HOLD_INPUT`); ``doc["settings"]["hold_input"]`` (in place) says what was held and why.  On the training samples
    the held model is the fitted one (the range is theirs)."""
    check_hold_input(rule)
    h = hysteresis_of(model)
    data = doc.get("data") or {}
    check = (doc.get("settings") or {}).get("hold_input_check") or {}
    cascade = thermal_of(model) is not None
    direct = h is not None and model is h
    key = "effective_input_range" if cascade else "input_range"
    rng = data.get(key)
    entry = {"rule": rule, "held": None}
    if h is None or not hasattr(h, "held") or not (direct or (cascade and hasattr(model, "with_hysteresis"))):
        entry["why"] = "the model has no hysteresis input to hold"
    elif rule == "off":
        entry["why"] = "hold_input off: the model extrapolates outside its trained range"
    elif check.get("chosen") == "extrapolating":
        entry["why"] = (
            f"{check['on']} leave the training range and were predicted better extrapolating (RMSE "
            f"{check['rmse_extrapolating']:.4g} against {check['rmse_held']:.4g} held): the model extrapolates"
        )
    elif not (isinstance(rng, (list, tuple)) and len(rng) == 2 and rng[1] > rng[0]):
        entry["why"] = f"no trained {key.replace('_', ' ')} in the fit: nothing to hold to"
    elif rule == "auto" and not direct and not rng[0] > 0.0:
        entry["why"] = "the training samples reached the ambient thermal state, the coldest there is: nothing to hold"
    else:
        from .._io import model_to_dict

        below = rule == "auto" and not direct  # a drive's thermal state: held below only (`COLD_SIDE`)
        lo, hi = float(rng[0]), None if below else float(rng[1])
        model = model.with_hysteresis(h.with_held(lo, hi))
        if "model" in doc:  # the fit.json's saved model is the held one
            doc["model"] = model_to_dict(model)
        entry.update(
            held=[lo, hi],
            of=key,
            why=(
                COLD_SIDE
                if below
                else "the hysteresis holds its input to the trained range: outside it the model does not extrapolate"
                + (
                    " (a measured input beyond its range: a sensor glitch or a material past its transformation)"
                    if direct
                    else ""
                )
            ),
        )
    doc.setdefault("settings", {})["hold_input"] = entry
    return model


def hold_on(model: Any, segments, rule: str = "auto") -> Any:
    """``model`` held by ``rule`` to the range of the samples it was trained on, ``segments`` = ``[(record, mask or
    None), ...]`` (each record run by its own start): what a split fit's or a leave-one-record-out fold's model is scored
    with, so that its held-out error is that of the model as it will be saved (`hold_fitted`)."""
    import numpy as np

    from ..models._hysteresis import record_model
    from ..models._range import effective_range, value_range

    check_hold_input(rule)
    masks = [np.ones(len(r), bool) if m is None else np.asarray(m, bool) for r, m in segments]
    data = {"input_range": value_range(np.concatenate([np.asarray(r.u)[m] for (r, _), m in zip(segments, masks)]))}
    if rule != "off" and thermal_of(model) is not None:
        eff = effective_range([(record_model(model, i), r.u, r.dt, m) for i, ((r, _), m) in enumerate(zip(segments, masks))])
        if eff is not None:
            data["effective_input_range"] = eff
    return hold_fitted(model, {"data": data}, rule)


def hold_choice(sse_held: float, sse_free: float, n: int, rule: str, on: str) -> tuple[str, dict]:
    """``("held" | "extrapolating", fit.json settings.hold_input_check)``: with ``rule`` "auto" the lower squared error of
    the held and the extrapolating model on ``on`` (held-out samples outside the training range) decides, a tie holds;
    "on" holds whatever they say.  Why the held-out samples decide: a measured input past its trained range was a sensor
    glitch or a saturated wire on the NiTi rig (held: 18.2 -> 3.9, 9.2 -> 1.2), but a pneumatic muscle goes on
    extending with pressure (cavatappi s2_t1's validation block, beyond its training pressures: 0.38 extrapolating,
    1.17 held)."""
    import numpy as np

    way = "extrapolating" if rule == "auto" and sse_free < sse_held else "held"
    rmse = lambda v: float(np.sqrt(v / max(int(n), 1)))
    return way, {"on": on, "rmse_held": rmse(sse_held), "rmse_extrapolating": rmse(sse_free), "chosen": way}
