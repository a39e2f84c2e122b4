"""Closed-loop control: the cascade plant under PID / composite PID (I-I compensator), batched sweeps
over configurations (vmap, sharded over devices) and the multi-process start-up for sweeps past one machine.
"""

from ._control import (
    PAPER_GAINS,
    PID,
    ClosedLoop,
    IICompensator,
    closed_loop_metrics,
    plant_init,
    plant_step,
    reachable_output,
    simulate_closed_loop,
    sine_reference,
    step_reference,
)
from ._distributed import ENV_ADDRESS, ENV_NUM_PROCESSES, ENV_PROCESS_ID, distributed_settings, initialize_from_env, to_host
from ._sweep import SweepResult, batch_configs, stack_models, sweep

__all__ = [
    "PID",
    "IICompensator",
    "ClosedLoop",
    "plant_init",
    "plant_step",
    "simulate_closed_loop",
    "closed_loop_metrics",
    "reachable_output",
    "sine_reference",
    "step_reference",
    "PAPER_GAINS",
    "sweep",
    "stack_models",
    "batch_configs",
    "SweepResult",
    "ENV_ADDRESS",
    "ENV_NUM_PROCESSES",
    "ENV_PROCESS_ID",
    "distributed_settings",
    "initialize_from_env",
    "to_host",
]
