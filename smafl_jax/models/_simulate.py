"""Jitted public entry points for running any model on an input record.

Bad input is reported in two tiers.  Concrete arrays (numpy, lists, JAX arrays outside a trace) are checked in
Python before anything is compiled, so the `UserInputError` names the argument, the first bad index and its value.
Traced values (``jax.jit(sj.simulate)``, a `vmap` over sample times) cannot be read there: the compiled function
checks them itself (`equinox.error_if`).
"""

from __future__ import annotations

from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax.typing import ArrayLike

from .. import _config  # noqa: F401
from .._errors import UserInputError
from ._hysteresis import hysteresis_of, thermal_of

__all__ = ["simulate", "simulate_batch"]

#: The ``dt`` a rate-independent model runs with when none is given: it never reads it (`uses_sample_time`).
UNUSED_DT = 1.0


def uses_sample_time(model: Any) -> bool:
    """Whether ``model``'s output depends on the sample time ``dt``.

    A hysteresis model on its own is rate-independent (`AbstractHysteresis`: its ``simulate`` ignores ``dt``; a
    hysteresis model is its own ``hysteresis`` part); every other model (a thermal lag, a cascade, an extended or
    recalibrated model, a user's class) is taken to need it.
    """
    h = hysteresis_of(model)
    return h is None or h is not model


def _is_traced(x: Any) -> bool:
    return isinstance(x, jax.core.Tracer)


def first_bad(x: np.ndarray) -> tuple[tuple[int, ...], float] | None:
    """``(index, value)`` of the first non-finite entry of ``x`` (row-major order), or None when all are finite."""
    bad = ~np.isfinite(x)
    if not bad.any():
        return None
    idx = np.unravel_index(int(np.flatnonzero(bad)[0]), x.shape)
    return tuple(int(i) for i in idx), float(x[idx])


def _where(idx: tuple[int, ...]) -> str:
    return f"index {idx[0]}" if len(idx) == 1 else f"index {idx}"


def _checked(u, dt):
    # Value checks that need the data: they run inside the compiled function
    # (equinox.error_if), so a bad value in a jitted sweep is caught too.
    u = eqx.error_if(u, ~jnp.all(jnp.isfinite(u)), "input record contains NaN or inf")
    dt = eqx.error_if(dt, ~(dt > 0), "sample time dt must be > 0")
    return u, dt


@eqx.filter_jit
def _simulate(model, u, dt):
    u, dt = _checked(u, dt)
    return model.simulate(u, dt)


@eqx.filter_jit
def _simulate_batch(model, u, dt):
    u, dt = _checked(u, dt)
    return jax.vmap(lambda x: model.simulate(x, dt))(u)


def check_sample_time(dt: Any, what: str = "dt") -> None:
    """`UserInputError` unless a concrete ``dt`` is one finite number > 0 (traced values are left to the compiled check)."""
    if _is_traced(dt):
        if jnp.ndim(dt) != 0:
            raise UserInputError(f"{what}: the sample time must be a scalar, got shape {jnp.shape(dt)}")
        return
    try:
        d = np.asarray(dt, dtype=np.float64)
    except (TypeError, ValueError):
        raise UserInputError(f"{what}: the sample time must be a number of seconds, got {dt!r}") from None
    if d.ndim != 0:
        raise UserInputError(f"{what}: the sample time must be a scalar, got shape {d.shape}")
    if not (np.isfinite(d) and d > 0):
        raise UserInputError(f"{what}: the sample time must be a finite number of seconds > 0, got {float(d)!r}")


def scalar_leaves_as_arrays(tree: Any) -> Any:
    """``tree`` with its Python ``float`` / ``int`` leaves as arrays (float64 for floats); bools and arrays unchanged.

    Why: every model field is an array after construction (the field converters), but ``eqx.tree_at(..., 0.05)`` puts
    a plain float back, and `eqx.filter_jit` treats a non-array leaf as static, so each new value compiled its own
    program (session 37 trial 3: 20 values of k1, 13.5 s against 0.02 s; likewise a PID gain in the closed loop)."""

    def convert(x):
        if isinstance(x, bool) or not isinstance(x, (int, float)):
            return x
        return jnp.asarray(x, dtype=jnp.float64) if isinstance(x, float) else jnp.asarray(x)

    return jax.tree_util.tree_map(convert, tree)


def compile_form(model: Any) -> Any:
    """``model`` in the form the jitted entry points take: structural choices that change no array shape held as data
    (`Cascade.compile_form`), so that models differing only in them share compiled programs; other models unchanged."""
    form = getattr(model, "compile_form", None)
    return model if form is None else form()


def user_form(model: Any) -> Any:
    """Inverse of `compile_form` (concrete models only): what a user holds, saves and reads."""
    form = getattr(model, "user_form", None)
    return model if form is None else form()


def compile_form_spec(model: Any, spec: Any) -> tuple[Any, Any]:
    """``(compile_form(model), spec)`` with ``spec`` (a trainable mask of ``model``) matched to it: the leaves the
    compile form adds are never trained."""
    formed = compile_form(model)
    if formed is model:
        return model, spec
    mask = dict(jax.tree_util.tree_flatten_with_path(spec)[0])
    paths, treedef = jax.tree_util.tree_flatten_with_path(formed)
    return formed, jax.tree_util.tree_unflatten(treedef, [mask.get(path, False) for path, _ in paths])


def _as_inputs(model, u, dt, ndim, call):
    name = "u" if ndim == 1 else "u (a batch of records)"
    shape_hint = "(one sample per time step)" if ndim == 1 else "(records, samples)"
    if _is_traced(u):
        u = jnp.asarray(u, dtype=jnp.float64)
    else:
        try:
            u_np = np.asarray(u, dtype=np.float64)
        except (TypeError, ValueError):
            raise UserInputError(f"{name}: expected an array of numbers, got {type(u).__name__}") from None
        if u_np.ndim != ndim:
            hint = ""
            if ndim == 1 and u_np.ndim == 2:
                hint = (
                    "; a column (N, 1): pass u[:, 0]; a batch of records (B, T): use sj.simulate_batch"
                    if u_np.shape[-1] == 1
                    else "; for a batch of records (B, T) use sj.simulate_batch"
                )
            raise UserInputError(f"{name}: the input must be {ndim}-D {shape_hint}, got shape {u_np.shape}{hint}")
        bad = first_bad(u_np)
        if bad is not None:
            raise UserInputError(f"{name}: the input is not finite at {_where(bad[0])} (value {bad[1]}); remove or fill it first")
        u = jnp.asarray(u_np)
    if u.ndim != ndim:
        raise UserInputError(f"{name}: the input must be {ndim}-D {shape_hint}, got shape {u.shape}")
    if u.shape[-1] < 2:
        raise UserInputError(f"{name}: the input record needs at least 2 samples, got {u.shape[-1]}")
    if dt is None:
        if uses_sample_time(model):
            raise UserInputError(
                f"dt (the sample time in seconds) is required: a {type(model).__name__}'s output depends on time; "
                f"pass it, e.g. {call}"
            )
        dt = UNUSED_DT
    check_sample_time(dt)
    k1 = getattr(thermal_of(model), "k1", None)
    if k1 is not None and not _is_traced(k1) and jnp.ndim(k1) > 0:
        # a stack of models (sj.stack_models) failed deeper down with a message about a joint fit's record starts, or a
        # broadcasting TypeError (session 37 trial 3)
        raise UserInputError(
            f"model: this {type(model).__name__} is a stack of {jnp.shape(k1)[0]} models (its thermal rate k1 has shape "
            f"{jnp.shape(k1)}; one model's is a scalar): run a batch of models with "
            "jax.vmap(sj.simulate, in_axes=(0, None, None))(models, u, dt)"
        )
    # dt goes in as an array so a new sample time never triggers a recompile.
    return u, jnp.asarray(dt, dtype=jnp.float64)


def simulate(model: eqx.Module, u: ArrayLike, dt: ArrayLike | None = None) -> jax.Array:
    """Model output for a 1-D input record ``u`` sampled every ``dt`` seconds (compiled once per shape).

    ``dt`` is required for every model whose output depends on time (a thermal lag, a cascade); a hysteresis model on
    its own is rate-independent and may omit it.  Bad concrete input raises `UserInputError` before compiling.
    """
    u, dt = _as_inputs(model, u, dt, 1, "sj.simulate(model, u, 0.05)")
    return _simulate(compile_form(scalar_leaves_as_arrays(model)), u, dt)


def simulate_batch(model: eqx.Module, u: ArrayLike, dt: ArrayLike | None = None) -> jax.Array:
    """Model outputs ``(B, T)`` for a batch of input records ``(B, T)`` (one `vmap`, one compile); ``dt`` as in `simulate`."""
    u, dt = _as_inputs(model, u, dt, 2, "sj.simulate_batch(model, u, 0.05)")
    return _simulate_batch(compile_form(scalar_leaves_as_arrays(model)), u, dt)
