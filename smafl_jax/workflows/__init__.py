"""Library workflows: whole analyses as functions that take Python objects and return results.

The ``smafl`` commands are thin layers over these (parse arguments, call, print);
the paper calls them directly.  Each workflow logs with `logging` and never prints.
"""

from .control import ControlResult, run_control
from .sample import SamplingResult, sample_posterior
from .simulate import SimulationResult, simulate_record
from .sweep import ControlSweepResult, run_sweep

__all__ = [
    "ControlResult",
    "ControlSweepResult",
    "SamplingResult",
    "SimulationResult",
    "run_control",
    "run_sweep",
    "sample_posterior",
    "simulate_record",
]
