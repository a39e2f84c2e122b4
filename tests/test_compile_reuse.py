"""Programs compiled once and reused (issue 18: half of a default fit's time is compilation).

- The Preisach relay recurrence, called outside a jitted caller, compiles once per shape, not once per call.
- The start screening profiles a one-record steady start in the "given" form (the state a constant u(0) would hold),
  so all thermal starts of one structure share a program; the losses must be those of the steady rule itself.
"""

import dataclasses
import sys
from pathlib import Path

import jax.numpy as jnp
import numpy as np
import pytest

import smafl_jax as sj
from smafl_jax.identify import screen_start

sys.path.insert(0, str(Path(__file__).parent))
import indep_plant
from compile_log import compiled_names


def test_preisach_relays_compile_once_outside_jit():
    a = sj.Preisach.from_range(0.0, 1.0, n_levels=7)
    b = a.with_linear_weights(jnp.linspace(-1.0, 1.0, a.linear_weights().size))  # other weights, same structure
    u1 = 0.5 + 0.45 * np.sin(np.linspace(0.0, 13.0, 333))
    u2 = 0.5 + 0.45 * np.cos(np.linspace(0.0, 7.0, 333))
    with compiled_names() as names:
        r = [np.asarray(m.relays(u)) for m in (a, b) for u in (u1, u2)]
        y = [np.asarray(m.simulate(u)) for m in (a, b) for u in (u1, u2)]
    assert sum("scan" in n for n in names) <= 2, names  # states, and weighted sum (a closure per call: 8)
    # the recurrence itself, against a plain numpy loop (crisp-or-ramp relays, up wins on a tie)
    lo_hi = [np.asarray(v) for v in a.thresholds()]
    width = float(a.width)
    state = np.asarray(a.initial_state(u1[0]), float)
    for k, uk in enumerate(u1):
        up = np.clip((uk - lo_hi[0]) / width + 0.5, 0.0, 1.0) if width > 0 else (uk >= lo_hi[0]).astype(float)
        down = np.clip((uk - lo_hi[1]) / width + 0.5, 0.0, 1.0) if width > 0 else (uk > lo_hi[1]).astype(float)
        state = np.maximum(np.minimum(state, down), up)
        np.testing.assert_allclose(r[0][k], state, atol=1e-12)
    assert np.all(np.isfinite(np.concatenate(y)))


def test_one_record_steady_start_is_screened_as_the_steady_rule():
    r = indep_plant.make_record(3, drive="multisine", rate_hz=5, minutes=2, start="warm")
    d = (r["u"], r["y"], r["dt"])
    start = sj.Cascade.from_range(float(np.max(r["u"])), n_sym=4, n_alpha=2, n_asym=2)
    kw = dict(k1_grid=4, orientation="rises", sees="voltage", thermal_start="steady", memory="descended")
    one, table1, _ = screen_start(start, [d], [np.ones(len(r["u"]))], **kw)
    # two copies of the record: the rule itself (several records keep it), every loss exactly twice one record's
    two, table2, _ = screen_start(start, [d, d], [np.ones(len(r["u"]))] * 2, **kw)
    assert one.thermal.init == "steady" and two.thermal.init == "steady" and one.thermal.u0 is None
    np.testing.assert_allclose([row["loss"] for row in table2], [2 * row["loss"] for row in table1], rtol=1e-9)
    np.testing.assert_allclose(float(one.thermal.k1), float(two.thermal.k1), rtol=1e-9)


@pytest.mark.slow  # suite time (session 70: 15-260 s on 2 cores)
def test_voltage_and_heat_cascades_share_their_compiled_programs():
    """What a cascade's hysteresis sees is data inside the jitted entry points (`Cascade.compile_form`): the start
    screening's voltage and heat candidates compiled every design, simulation and LM solve twice before (session 52:
    13 of the 34 s a 30 000-sample `--model cascade` fit spent compiling)."""
    u = 2.5 + 2.4 * np.sin(np.linspace(0.0, 9.0, 347))  # a length no other test uses: the first call compiles
    plain = sj.Cascade.from_range(5.0, n_sym=4, n_alpha=2, n_asym=2)
    volt, heat = (m.with_hysteresis(m.hysteresis.with_linear_weights(np.linspace(0.5, 1.5, m.hysteresis.linear_weights().size)))
                  for m in (plain, plain.with_sees("heat", 5.0)))  # fmt: skip
    with compiled_names() as names:
        yv, yh = (np.asarray(sj.simulate(m, u, 0.2)) for m in (volt, heat))
    assert sum("_simulate" in n for n in names) == 1, names
    # each the output of its own static branch (op by op), and the two classes differ
    np.testing.assert_allclose(yv, np.asarray(volt.simulate(u, 0.2)), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(yh, np.asarray(heat.simulate(u, 0.2)), rtol=1e-12, atol=1e-12)
    assert np.max(np.abs(yv - yh)) > 0.1 * np.ptp(yv)
    # a fit hands back what a user holds and saves: the static choice, no compile-form leaf
    y = yh + 0.01 * np.random.default_rng(0).standard_normal(u.size)
    fitted = sj.fit(heat, (u, y), 0.2, max_steps=5).model
    assert fitted.sees == "heat" and fitted.heat_input is None
    assert "heat_input" not in sj.model_to_dict(fitted)
    with pytest.raises(sj.UserInputError, match="compile form"):
        sj.model_to_dict(heat.compile_form())
    with pytest.raises(ValueError, match="sees"):
        sj.Cascade(thermal=volt.thermal, hysteresis=volt.hysteresis, sees="data")


def test_both_output_signs_share_their_compiled_programs():
    """The output orientation is data inside the jitted entry points (`AbstractHysteresis.compile_form`): the start
    screening's two signs, and the refinement of a record whose sign stays open, compiled everything twice before."""
    u = 0.5 + 0.45 * np.sin(np.linspace(0.0, 11.0, 353))  # a length no other test uses
    up = sj.EUPI.from_range(0.0, 1.0, n_sym=3, n_alpha=2, n_asym=2)
    up = up.with_linear_weights(np.linspace(0.5, 1.5, up.linear_weights().size))
    down = dataclasses.replace(up, orientation=-1)
    with compiled_names() as names:
        y_up, y_down = (np.asarray(sj.simulate(m, u)) for m in (up, down))
    assert sum("_simulate" in n for n in names) == 1, names
    np.testing.assert_allclose(y_up, np.asarray(up.simulate(u)), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(y_down, np.asarray(down.simulate(u)), rtol=1e-12, atol=1e-12)
    fitted = sj.fit(down, (u, y_down + 0.01 * np.random.default_rng(1).standard_normal(u.size)), max_steps=5).model
    assert fitted.orientation == -1 and fitted.sign is None
    with pytest.raises(ValueError, match="orientation"):
        dataclasses.replace(up, orientation=0)  # 0 only with the compile form's sign leaf
