"""Batched closed-loop sweeps: `jax.vmap` over configurations, batch axis sharded over devices.

A sweep starts from one `ClosedLoop` and a ``grid`` mapping *paths* to values:
``{"pid.kp": [10, 35, 60], "compensator.K": [0, 10], "plant": stacked_models}``.
A path names a field (dots for nesting); its value is a 1-D array of numbers
or, for a model-valued field (``"plant"``, ``"compensator.model"``), a stacked
PyTree whose array leaves share a leading axis (e.g. posterior draws; see
`stack_models`).  ``"reference"`` takes a ``(n, T)`` array.  Only swept leaves
get a batch axis (`vmap` ``in_axes`` 0); everything else is broadcast
(``in_axes=None``), so a 10,000-config sweep does not copy the reference or the
models 10,000 times.

Devices: the batch is padded (repeating the last configuration) to a multiple
of ``len(jax.devices())`` and placed with a `NamedSharding` over a 1-D mesh
(axis ``"batch"``); unswept leaves are replicated.  The same code therefore uses
one CPU, several forced host devices, or several GPUs.
"""

from __future__ import annotations

import functools
import time
from collections.abc import Iterable
from typing import NamedTuple, TypeVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh, NamedSharding, PartitionSpec

from .. import _config  # noqa: F401
from ..models._simulate import scalar_leaves_as_arrays
from ._control import ClosedLoop, _check_dt, _scan_loop
from ._distributed import to_host

__all__ = ["sweep", "stack_models", "batch_configs", "SweepResult"]


class SweepResult(NamedTuple):
    """Metrics arrays shaped like the grid (``shape``), and the swept values per axis."""

    metrics: dict  # name -> np.ndarray of shape `shape`
    shape: tuple
    names: tuple  # swept paths, in grid-axis order
    values: dict  # path -> the values given (numpy, or the stacked model)


_Tree = TypeVar("_Tree")


def stack_models(models: Iterable[_Tree]) -> _Tree:
    """Stack models of identical structure into one PyTree with a leading batch axis on every array leaf."""
    models = list(models)
    if not models:
        raise ValueError("stack_models needs at least one model")
    return jax.tree.map(lambda *xs: jnp.stack([jnp.asarray(x) for x in xs]), *models)


def _getter(path):
    parts = path.split(".")

    def get(tree):
        return functools.reduce(getattr, parts, tree)

    return get


def _leading(value):
    leaves = jax.tree.leaves(value)
    if not leaves:
        raise ValueError("a swept value has no array leaves")
    sizes = {np.shape(x)[0] if np.ndim(x) else None for x in leaves}
    if len(sizes) != 1 or None in sizes:
        raise ValueError(f"every array leaf of a swept value needs the same leading (batch) axis, got sizes {sizes}")
    return sizes.pop()


def batch_configs(base: ClosedLoop, grid: dict, mode="product"):
    """Batched config, matching ``in_axes`` PyTree, and grid shape.

    ``mode="product"``: every combination (shape = one axis per path);
    ``mode="zip"``: the values are taken together, one config per index (shape ``(n,)``).
    """
    if not isinstance(base, ClosedLoop):
        raise TypeError(f"base must be a ClosedLoop, got {type(base).__name__}")
    if not grid:
        raise ValueError("grid is empty: give at least one path -> values entry")
    names = tuple(grid)
    values, sizes = {}, []
    for name in names:
        current = base
        for part in name.split("."):
            if current is None:
                break
            if not hasattr(current, part):
                raise ValueError(f"sweep path {name!r} does not name a field of the closed-loop configuration")
            current = getattr(current, part)
        if current is None:
            raise ValueError(f"sweep path {name!r} is None in the base configuration (composite sweeps need a compensator)")
        v = grid[name]
        if isinstance(current, eqx.Module):
            if jax.tree.structure(v) != jax.tree.structure(current):
                raise ValueError(f"sweep value for {name!r} must be a stacked PyTree of the same structure as the base field")
        else:
            v = np.asarray(v, dtype=np.float64)
            if v.ndim != np.ndim(current) + 1:
                raise ValueError(f"sweep values for {name!r} must have shape (n, *{np.shape(current)}), got {v.shape}")
        values[name] = v
        sizes.append(_leading(v))
    if mode == "product":
        shape = tuple(sizes)
        idx = [i.ravel() for i in np.meshgrid(*[np.arange(n) for n in sizes], indexing="ij")]
    elif mode == "zip":
        if len(set(sizes)) != 1:
            raise ValueError(f"mode='zip' needs equal numbers of values per path, got {dict(zip(names, sizes))}")
        shape = (sizes[0],)
        idx = [np.arange(sizes[0])] * len(names)
    else:
        raise ValueError(f"mode must be 'product' or 'zip', got {mode!r}")

    config = base
    axes = jax.tree.map(lambda _: None, base)
    for name, ix in zip(names, idx):
        get = _getter(name)
        new = jax.tree.map(lambda x: jnp.asarray(x)[ix], values[name])
        config = eqx.tree_at(get, config, new)
        axes = eqx.tree_at(get, axes, jax.tree.map(lambda _: 0, new), is_leaf=lambda x: x is None)
    return config, axes, shape, names, values


def _mesh():
    return Mesh(np.asarray(jax.devices()), ("batch",))


#: Closed-loop sample steps per compiled call (configurations x samples); bounds memory and sets
#: how often progress is reported.  A sweep of any size compiles once: every chunk has the same shape.
CHUNK_STEPS = 4_000_000


def sweep(
    base: ClosedLoop,
    dt: float,
    grid: dict,
    *,
    mode: str = "product",
    shard: bool = True,
    chunk: int | None = None,
    progress: bool | None = None,
) -> SweepResult:
    """Metrics (e_mean_mm, rmse_mm, max_abs_error_mm, saturated_fraction, u_min_V, u_max_V) for every grid configuration.

    The configurations run in chunks of ``chunk`` (default: about `CHUNK_STEPS`
    sample steps per chunk, rounded to a multiple of the device count; the last
    chunk is padded by repeating its last configuration; a sweep smaller than a
    chunk runs at its size rounded up, so sweeps of nearby sizes share one
    compiled program).  ``progress(done,
    total, elapsed_s)`` is called after each chunk.
    """
    dt = _check_dt(dt)
    base = scalar_leaves_as_arrays(base)  # a float set by tree_at is static under jit: one compile per value
    config, axes, shape, names, values = batch_configs(base, grid, mode)
    n = int(np.prod(shape))
    arrays, static = eqx.partition(config, eqx.is_array)
    ax_arrays = jax.tree.map(lambda a, _: a, axes, arrays, is_leaf=lambda x: x is None)
    n_dev = len(jax.devices()) if shard else 1
    n_time = int(np.shape(base.reference)[-1])
    size = int(chunk) if chunk is not None else max(1, CHUNK_STEPS // max(n_time, 1))
    if size < 1:
        raise ValueError(f"chunk must be >= 1, got {chunk}")
    if n < size:  # a sweep smaller than one chunk: its size rounded up, so sweeps of nearby sizes share one program
        size = _rounded_up(n)
    size = -(-size // n_dev) * n_dev

    flat_x, tdef = jax.tree.flatten(arrays)
    flat_ax = tdef.flatten_up_to(ax_arrays)
    batched = replicated = None
    if shard and n_dev > 1:
        mesh = _mesh()
        batched, replicated = NamedSharding(mesh, PartitionSpec("batch")), NamedSharding(mesh, PartitionSpec())
        flat_x = [x if a == 0 else jax.device_put(x, replicated) for x, a in zip(flat_x, flat_ax)]

    def piece(x, lo, hi):
        part = x[lo:hi]
        if hi - lo < size:
            part = jnp.concatenate([part, jnp.repeat(part[-1:], size - (hi - lo), axis=0)])
        return part if batched is None else jax.device_put(part, batched)

    parts = []
    t0 = time.monotonic()
    for lo in range(0, n, size):
        hi = min(n, lo + size)
        xs = [piece(x, lo, hi) if a == 0 else x for x, a in zip(flat_x, flat_ax)]
        out = _run_partitioned(jax.tree.unflatten(tdef, xs), static, tuple(flat_ax), tdef, dt)
        # to_host: with several processes (jax.distributed) the result is sharded across them; gather it everywhere
        parts.append({k: v[: hi - lo] for k, v in to_host(out).items()})
        if progress is not None:
            progress(hi, n, time.monotonic() - t0)
    metrics = {k: np.concatenate([p[k] for p in parts]).reshape(shape) for k in parts[0]}
    return SweepResult(metrics, shape, names, values)


def _rounded_up(n: int) -> int:
    """``n`` rounded up to a multiple of 2**(bits - 3): at most 25 % padding, four chunk shapes per doubling of the
    sweep size (each new size compiled its own program: 1.4 s for a 12x10 grid after a 10x10 one, session 37)."""
    step = 1 << max(int(n).bit_length() - 3, 0)
    return -(-int(n) // step) * step


@eqx.filter_jit
def _run_partitioned(arrays, static, flat_ax, tdef, dt):
    ax_tree = jax.tree.unflatten(tdef, list(flat_ax))

    def one(a):
        return _scan_loop(eqx.combine(a, static), dt, False)[0]

    return jax.vmap(one, in_axes=(ax_tree,))(arrays)
