"""Sweeps over several processes with jax.distributed (issue 15): two CPU processes on a loopback coordinator."""

import os
import socket
import subprocess
import sys
import textwrap
from pathlib import Path

import jax.numpy as jnp
import numpy as np
import pytest

import smafl_jax as sj
from smafl_jax import UserInputError
from smafl_jax.control import (
    ENV_ADDRESS,
    ENV_NUM_PROCESSES,
    ENV_PROCESS_ID,
    PID,
    ClosedLoop,
    IICompensator,
    distributed_settings,
    initialize_from_env,
    step_reference,
    sweep,
)

ROOT = Path(__file__).resolve().parents[1]
DT = 0.05
KPS = np.linspace(5.0, 50.0, 5)
KS = np.array([0.0, 10.0])  # 10 configurations over 4 global devices: padded to 12


def _base(truth):
    return ClosedLoop(
        plant=truth, pid=PID(), reference=jnp.asarray(step_reference(4, DT)), compensator=IICompensator(truth, 10.0)
    )


# Each process: start jax.distributed from the environment, run the ordinary sweep, save what it gathered.
_WORKER = textwrap.dedent(
    """
    import sys
    import numpy as np
    import smafl_jax as sj
    from smafl_jax.control import initialize_from_env
    assert initialize_from_env(), "no distributed settings in the environment"
    import jax
    import jax.numpy as jnp
    from smafl_jax.control import PID, ClosedLoop, IICompensator, step_reference, sweep
    assert jax.process_count() == 2 and jax.local_device_count() == 2 and jax.device_count() == 4, jax.devices()
    truth = sj.load_model(sys.argv[1])
    dt = {dt}
    base = ClosedLoop(plant=truth, pid=PID(), reference=jnp.asarray(step_reference(4, dt)), compensator=IICompensator(truth, 10.0))
    res = sweep(base, dt, {{"pid.kp": np.array({kps}), "compensator.K": np.array({ks})}})
    np.savez(sys.argv[2], **res.metrics)
    print("process", jax.process_index(), "done")
    """
).format(dt=DT, kps=KPS.tolist(), ks=KS.tolist())


def _free_port():
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_two_process_sweep_gathers_the_single_process_result(tmp_path):
    script = tmp_path / "worker.py"
    script.write_text(_WORKER)
    port = _free_port()
    procs = []
    for pid in range(2):
        env = dict(
            os.environ,
            JAX_PLATFORMS="cpu",
            XLA_FLAGS="--xla_force_host_platform_device_count=2",
            **{ENV_ADDRESS: f"127.0.0.1:{port}", ENV_NUM_PROCESSES: "2", ENV_PROCESS_ID: str(pid)},
        )
        cmd = [sys.executable, str(script), str(ROOT / "datasets" / "truth.json"), str(tmp_path / f"p{pid}.npz")]
        procs.append(subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True))
    # the single-process reference runs meanwhile (this process: no jax.distributed, its own devices)
    truth = sj.load_model(ROOT / "datasets" / "truth.json")
    ref = sweep(_base(truth), DT, {"pid.kp": KPS, "compensator.K": KS}, shard=False).metrics
    outputs = []
    try:
        for p in procs:
            out, err = p.communicate(timeout=240)
            outputs.append((p.returncode, out, err))
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
    for pid, (rc, _out, err) in enumerate(outputs):
        assert rc == 0, f"process {pid} failed:\n{err[-3000:]}"
    for pid in range(2):
        got = np.load(tmp_path / f"p{pid}.npz")
        assert set(got.files) == set(ref)
        for k in ref:
            assert got[k].shape == (len(KPS), len(KS))
            np.testing.assert_allclose(got[k], ref[k], rtol=1e-12, atol=1e-14, err_msg=f"process {pid}, {k}")


def test_settings_absent_means_single_process():
    assert distributed_settings({}) is None
    assert initialize_from_env({}) is False


def test_settings_parsed_and_bad_settings_named():
    env = {ENV_ADDRESS: "10.0.0.1:1234", ENV_NUM_PROCESSES: "4", ENV_PROCESS_ID: "3"}
    assert distributed_settings(env) == {"coordinator_address": "10.0.0.1:1234", "num_processes": 4, "process_id": 3}
    with pytest.raises(UserInputError, match=f"{ENV_PROCESS_ID} missing"):
        distributed_settings({ENV_ADDRESS: "h:1", ENV_NUM_PROCESSES: "2"})
    with pytest.raises(UserInputError, match="HOST:PORT"):
        distributed_settings({**env, ENV_ADDRESS: "10.0.0.1"})
    with pytest.raises(UserInputError, match="integer"):
        distributed_settings({**env, ENV_NUM_PROCESSES: "two"})
    with pytest.raises(UserInputError, match=r"in 0\.\.3"):
        distributed_settings({**env, ENV_PROCESS_ID: "4"})
