"""Records, loading, data checks and splits (numpy only, no JAX import of its own: `smafl check` needs no JAX).

- `Record`, `load_record`, `load_records`, `resample_record`: reading CSV files (+ JSON sidecar).
- `check_record`, `check_records`, `Finding`: faults in the data (jumps, spikes, flat runs, sampling, ...).
- `Segment`, `Split` and the split rules (`time_block`, `branches`, `interleaved`, `leave_one_record_out`,
  `blocked_folds`, `whole`, `make_split`) with `coverage`: one split module for fit, diagnose and CV.
"""

from .checks import ACTIONS, Finding, check_record, check_records
from .load import INPUT_CANDIDATES, OUTPUT_CANDIDATES, file_sha256, load_record, load_records, resample_record
from .record import DEFAULT_DT_RTOL, Record
from .split import (
    SPLIT_KINDS,
    Segment,
    Split,
    blocked_folds,
    branch_coverage,
    branches,
    coverage,
    interleaved,
    leave_one_record_out,
    load_column,
    make_split,
    masks,
    time_block,
    whole,
)

__all__ = [
    "ACTIONS",
    "DEFAULT_DT_RTOL",
    "INPUT_CANDIDATES",
    "OUTPUT_CANDIDATES",
    "Finding",
    "Record",
    "SPLIT_KINDS",
    "Segment",
    "Split",
    "blocked_folds",
    "branches",
    "coverage",
    "branch_coverage",
    "interleaved",
    "leave_one_record_out",
    "load_column",
    "make_split",
    "masks",
    "time_block",
    "whole",
    "check_record",
    "check_records",
    "file_sha256",
    "load_record",
    "load_records",
    "resample_record",
]
