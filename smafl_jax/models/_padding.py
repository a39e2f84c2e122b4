"""Causal calls on inputs padded to a few bucket lengths, so that records of many lengths share compilations.

A jitted scan compiles once per input length.  A diagnosis or a Preisach cross-validation simulates many
branches and blocks of different lengths (353 compilations, about half the run time, on the 642-sample
FORC record of the paper run), though each simulation itself takes microseconds.  Every model here is
causal (output k depends on inputs 0..k only), so running it on the input padded at the end (last value
repeated) and dropping the padded samples gives the same output; the lengths are rounded up to at least
`MIN_BUCKET` and beyond that to a multiple of an eighth of their power of two (at most 12.5 % more work).
`smafl_jax.fit` pads its records so (`pad_records`: the padded samples get weight 0).  A model class whose output at a
sample depends on later inputs (none here) sets ``causal = False``; `fit` then leaves its records as they are.
"""

from __future__ import annotations

import numpy as np

__all__ = ["bucket_length", "pad_records", "padded_call"]

#: Every input up to this length shares one compilation.
MIN_BUCKET = 256


def bucket_length(n: int) -> int:
    """The padded length for ``n`` samples: ``MIN_BUCKET``, or ``n`` rounded up to a multiple of 2**(bits - 4)."""
    n = int(n)
    if n <= MIN_BUCKET:
        return MIN_BUCKET
    step = 1 << max(n.bit_length() - 4, 0)
    return -(-n // step) * step


def _pad(x, total):
    x = np.asarray(x)
    if x.shape[0] == total:
        return x
    return np.concatenate([x, np.repeat(x[-1:], total - x.shape[0], axis=0)])


def pad_records(data, weights):
    """Fit records ``(u, y, dt)`` and their sample weights padded at the end to `bucket_length` samples.

    The input and the output repeat their last sample (finite, and the model's state stays where the record left it);
    the weights of the padded samples are 0, so a weighted loss, a design with its zero-weight rows dropped and a count
    of weighted samples are those of the records as given.
    """
    out_data, out_weights = [], []
    for (u, y, d), w in zip(data, weights):
        total = bucket_length(np.shape(u)[0])
        out_data.append((_pad(u, total), _pad(y, total), d))
        w = np.asarray(w, dtype=np.float64)
        out_weights.append(np.concatenate([w, np.zeros(total - w.shape[0])]))
    return tuple(out_data), tuple(out_weights)


def padded_call(fn, model, series, *rest):
    """``fn(model, *series_padded, *rest)`` cut back to the original length along the first axis.

    ``series``: the per-sample inputs (a tuple of arrays of equal length, or None entries passed as they are).
    """
    import jax.numpy as jnp

    n = next(np.shape(s)[0] for s in series if s is not None)
    if n == 0:
        return np.asarray(fn(model, *(None if s is None else jnp.asarray(s) for s in series), *rest))
    total = bucket_length(n)
    padded = tuple(None if s is None else jnp.asarray(_pad(s, total)) for s in series)
    return np.asarray(fn(model, *padded, *rest))[:n]
