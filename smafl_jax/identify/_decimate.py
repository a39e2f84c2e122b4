"""A shorter view of a long Joule-driven record for fitting: block-RMS drive, block-end output.

The fit of a voltage-driven model scans the whole record hundreds of times (start screening, the
(k1, u0) search, LM Jacobians), so its cost grows with the sample count, while what it identifies
does not: the thermal time constants of these actuators are 10-100 s and the hysteresis sees the
slow thermal state.  A 20-minute record at 100 Hz (120 000 samples) is therefore fitted at a few
Hz, the drive decimated the right way (the output samples dropped between block ends do cost
precision: hence `MAX_STRIDE`):

- the drive of block ``j`` (``stride`` samples) becomes the RMS of the block, because the thermal
  state integrates ``U^2`` (Joule heat): the heat delivered per block is exact, the state at the block
  end differs from the full-rate one by ``O(k1 * stride * dt)`` times the ripple of ``U^2`` inside
  the block (PWM at any frequency is averaged correctly; sampling a PWM voltage instead would alias);
- the output of block ``j`` is its last sample (not the mean, which would lag half a block): the
  noise per sample is unchanged, so the RMSE keeps its meaning;
- the record then starts at the end of the first block, whose interval covers the first samples:
  a thermal start state refers to the same instant.

Only models with a Joule thermal part (``thermal``) are fitted on the view; the saved model is the
same PyTree and is simulated and scored at the record's own rate.
"""

from __future__ import annotations

import dataclasses

import numpy as np

#: Records longer than this (samples) are fitted on a decimated view.
DECIMATE_ABOVE = 20_000
#: Target length of the view (samples).
TARGET_SAMPLES = 6_000
#: Longest sample time of the view (s): keeps ``k1 * dt`` small for fast actuators (k1 up to ~1 1/s).
MAX_VIEW_DT = 0.25
#: Largest decimation factor.  The view keeps one output sample per block, so a larger stride throws away output
#: samples (and the noise averaging they give), not only redundant drive samples.  Measured on independent 10-minute
#: 100 Hz records (60 000 samples; commands in .notes/session14_note.md): held-out RMSE / noise
#: at stride 10 -> 5: multisine cold s13 3.36 -> 1.25, PWM cold s17 2.63 -> 1.93, PWM cold s7 17.0 -> 11.6, three
#: records unchanged (PWM s13 1.01, multisine s11 1.14 -> 1.16, warm multisine s19 1.02); the fit took 1.1-1.7x as long.
MAX_STRIDE = 5


def fit_stride(n: int, dt: float) -> int:
    """Decimation factor for a record of ``n`` samples at ``dt`` (1 = fit at full rate)."""
    if n <= DECIMATE_ABOVE:
        return 1
    return max(1, min(int(np.ceil(n / TARGET_SAMPLES)), int(np.floor(MAX_VIEW_DT / dt)), MAX_STRIDE))


def decimate_record(record, stride: int):
    """Record of ``len(record) // stride`` blocks: RMS drive, last output, last time of each block."""
    n = (len(record) // stride) * stride
    if stride <= 1 or n < 2 * stride:
        return record
    u = np.asarray(record.u[:n], dtype=np.float64).reshape(-1, stride)
    end = np.arange(stride - 1, n, stride)
    return dataclasses.replace(
        record,
        time=np.asarray(record.time)[end],
        u=np.sqrt(np.mean(u * u, axis=1)),  # Joule heat depends on U^2 only
        y=None if record.y is None else np.asarray(record.y)[end],
        dt=float(record.dt) * stride,
        extra={k: np.asarray(v)[end] for k, v in record.extra.items()},
        processing=tuple(record.processing) + (f"fitted on a view decimated by {stride} (block-RMS drive, block-end output)",),
    )


def decimate_mask(mask: np.ndarray, stride: int) -> np.ndarray:
    """A sample mask on the view: a block belongs where its last sample does."""
    mask = np.asarray(mask)
    n = (len(mask) // stride) * stride
    return mask[stride - 1 : n : stride] if stride > 1 else mask


def fit_view(record, model, masks):
    """``(view, view_masks, info)``: the record a fit runs on, with its masks; ``info`` None at full rate."""
    stride = fit_stride(len(record), float(record.dt)) if hasattr(model, "thermal") else 1
    if stride <= 1:
        return record, masks, None
    view = decimate_record(record, stride)
    info = {
        "stride": stride,
        "n_samples": len(view),
        "sample_time_s": float(view.dt),
        "rule": (
            f"records longer than {DECIMATE_ABOVE} samples with a Joule thermal part are fitted on a view of about "
            f"{TARGET_SAMPLES} samples (sample time <= {MAX_VIEW_DT} s; stride <= {MAX_STRIDE}, so longer views of long "
            "high-rate records): block-RMS drive (exact heat per block), block-end "
            "output; metrics are computed at the record's own rate"
        ),
    }
    return view, [decimate_mask(m, stride) for m in masks], info
