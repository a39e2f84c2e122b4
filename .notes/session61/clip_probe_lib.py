import numpy as np
from smafl_jax.models._hysteresis import hysteresis_of, thermal_of
def sim_clipped(model, u, dt, rng):
    h = hysteresis_of(model)
    if h is None: return None
    if thermal_of(model) is not None:
        if type(model).__name__ != "Cascade": return None
        x = np.asarray(model.hysteresis_input(u, dt))
    elif model is h:
        x = np.asarray(u)
    else:
        return None
    return np.asarray(h.simulate(np.clip(x, rng[0], rng[1])))

def sim_ops_held(model, u, dt, rng):
    """EUPI only: the play operators see the input held to rng; the linear and polynomial terms see it as is."""
    import jax.numpy as jnp
    from smafl_jax.models._eupi import poly_columns
    from smafl_jax.models._operators import play_weighted
    h = hysteresis_of(model)
    if h is None or type(h).__name__ != "EUPI": return None
    if thermal_of(model) is not None:
        if type(model).__name__ != "Cascade": return None
        x = np.asarray(model.hysteresis_input(u, dt))
    elif model is h:
        x = np.asarray(u)
    else:
        return None
    s = h.normalise(x); sc = h.normalise(np.clip(x, rng[0], rng[1]))
    r, a = h._bank(); w = jnp.concatenate([h.v, jnp.ravel(h.w)])
    ops = play_weighted(sc, r, a, w, y0=h._initial_state(sc[0], r, a), method=h.method)
    poly = poly_columns(s, np.shape(h.poly)[0]) @ h.poly
    return np.asarray(h.orientation_sign() * (h.gain * s + ops) + poly + h.offset)
