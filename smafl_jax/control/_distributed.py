"""Sweeps past one machine: `jax.distributed` start-up from the environment, and a multi-process sweep.

Every host runs the same program (JAX's multi-controller model).  Start it with three
environment variables and call `initialize_from_env` before any JAX computation:

    JAX_COORDINATOR_ADDRESS=host0:12345   # process 0's address and a free port, the same for every process
    JAX_NUM_PROCESSES=4                   # number of processes (hosts, or processes per host x hosts)
    JAX_PROCESS_ID=0                      # 0 .. JAX_NUM_PROCESSES - 1, different on every process

(``JAX_LOCAL_DEVICE_IDS`` optionally restricts the devices of one process; JAX reads it itself.)
Under Slurm or Open MPI leave the three unset and pass ``auto=True``: JAX detects them.

`smafl_jax.sweep` then runs over the *global* device mesh (all devices of all processes):
every process builds the same configuration batch (so the grid must be the same everywhere;
`jax.device_put` checks it), the batch axis is sharded over the global devices, each process
computes only the configurations on its own devices, and `to_host` gathers the metrics to every
process with `jax.experimental.multihost_utils.process_allgather`.  Write results from process 0
only (``jax.process_index() == 0``).
"""

from __future__ import annotations

import logging
import os
from collections.abc import Mapping

import jax
import numpy as np
from jax.experimental import multihost_utils

from .. import _config  # noqa: F401
from .._errors import UserInputError

__all__ = ["ENV_ADDRESS", "ENV_NUM_PROCESSES", "ENV_PROCESS_ID", "distributed_settings", "initialize_from_env", "to_host"]

log = logging.getLogger(__name__)

ENV_ADDRESS = "JAX_COORDINATOR_ADDRESS"
ENV_NUM_PROCESSES = "JAX_NUM_PROCESSES"
ENV_PROCESS_ID = "JAX_PROCESS_ID"


def _int_var(env: Mapping[str, str], name: str) -> int:
    text = env[name].strip()
    try:
        return int(text)
    except ValueError:
        raise UserInputError(f"environment variable {name}={env[name]!r} must be an integer") from None


def distributed_settings(environ: Mapping[str, str] | None = None) -> dict | None:
    """``{coordinator_address, num_processes, process_id}`` from the environment; None when none is set.

    Raises `UserInputError` when only some are set or a value is malformed (a half-configured
    cluster would otherwise hang until JAX's initialisation timeout).
    """
    env = os.environ if environ is None else environ
    names = (ENV_ADDRESS, ENV_NUM_PROCESSES, ENV_PROCESS_ID)
    present = [n for n in names if env.get(n, "").strip()]
    if not present:
        return None
    if len(present) != len(names):
        missing = [n for n in names if n not in present]
        raise UserInputError(f"multi-process run: {', '.join(present)} set but {', '.join(missing)} missing; set all three")
    address = env[ENV_ADDRESS].strip()
    host, sep, port = address.rpartition(":")
    if not sep or not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise UserInputError(f"environment variable {ENV_ADDRESS}={address!r} must be HOST:PORT (e.g. 10.0.0.1:12345)")
    num, pid = _int_var(env, ENV_NUM_PROCESSES), _int_var(env, ENV_PROCESS_ID)
    if num < 1:
        raise UserInputError(f"environment variable {ENV_NUM_PROCESSES}={num} must be >= 1")
    if not 0 <= pid < num:
        raise UserInputError(f"environment variable {ENV_PROCESS_ID}={pid} must be in 0..{num - 1} ({ENV_NUM_PROCESSES}={num})")
    return {"coordinator_address": address, "num_processes": num, "process_id": pid}


def initialize_from_env(environ: Mapping[str, str] | None = None, *, auto: bool = False, timeout_s: int = 300) -> bool:
    """Call `jax.distributed.initialize` from the environment variables above; True when it ran (or had run).

    Without the variables: nothing happens (single process) and False is returned, unless
    ``auto=True``, which lets JAX detect a Slurm / Open MPI / TPU cluster.  Must run before
    any JAX computation in the process.
    """
    if jax.distributed.is_initialized():
        return True
    settings = distributed_settings(environ)
    if settings is None:
        if not auto:
            log.info("no %s in the environment: single-process run", ENV_ADDRESS)
            return False
        jax.distributed.initialize(initialization_timeout=timeout_s)
    else:
        # all three given: skip JAX's cluster auto-detection (a stray Slurm variable must not override them)
        jax.distributed.initialize(**settings, initialization_timeout=timeout_s, cluster_detection_method="deactivate")
    log.info("jax.distributed: process %d of %d, %d global devices", jax.process_index(), jax.process_count(), jax.device_count())
    return True


def to_host(tree):
    """PyTree of arrays as numpy on this process, gathered from every process when they are sharded across processes.

    A result sharded over the global mesh is not fully addressable by one process;
    `multihost_utils.process_allgather` (a collective: every process must call it) returns its full value.
    """

    def one(x):
        if isinstance(x, jax.Array) and not x.is_fully_addressable:
            return np.asarray(multihost_utils.process_allgather(x, tiled=True))
        return np.asarray(x)

    return jax.tree.map(one, tree)
