import numpy as np
from smafl_jax.models._hysteresis import hysteresis_of, thermal_of


def _hyst_input(model, u, dt):
    """(hysteresis, what it sees along u) for a Cascade or a hysteresis on its own, else (None, None)."""
    h = hysteresis_of(model)
    if h is None:
        return None, None
    if thermal_of(model) is not None:
        return (h, np.asarray(model.hysteresis_input(u, dt))) if type(model).__name__ == "Cascade" else (None, None)
    return (h, np.asarray(u)) if model is h else (None, None)


def sim_clipped(model, u, dt, rng):
    h, x = _hyst_input(model, u, dt)
    return None if h is None else np.asarray(h.simulate(np.clip(x, rng[0], rng[1])))


def sim_ops_held(model, u, dt, rng):
    """EUPI only: the play operators see the input held to rng; the linear and polynomial terms see it as is."""
    import jax.numpy as jnp
    from smafl_jax.models._eupi import poly_columns
    from smafl_jax.models._operators import play_weighted
    h, x = _hyst_input(model, u, dt)
    if h is None or type(h).__name__ != "EUPI":
        return None
    s = h.normalise(x); sc = h.normalise(np.clip(x, rng[0], rng[1]))
    r, a = h._bank(); w = jnp.concatenate([h.v, jnp.ravel(h.w)])
    ops = play_weighted(sc, r, a, w, y0=h._initial_state(sc[0], r, a), method=h.method)
    poly = poly_columns(s, np.shape(h.poly)[0]) @ h.poly
    return np.asarray(h.orientation_sign() * (h.gain * s + ops) + poly + h.offset)
