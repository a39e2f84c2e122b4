"""The pointwise median of several models' outputs: a combination of model classes that one bad class cannot move.

Why (session 28, experiments/results/random_levels_20min_session28.md): on 60 records of the two independent plants,
each fitted on its first 70 % as every class `--model auto` compares (EUPI, Preisach and Gaussian-Preisach cascades),
the median of the three predictions held out 0.88x the geometric-mean error of the class the validation block keeps
(7.84x -> 6.88x the noise), with as many records within 1.5x and 3x; it cuts the blow-ups of one class on an untrained
branch (random multi-level and plant-B records), but on issue 18's matrix, where one class reaches the noise and the
others do not, it is slightly worse (4.67x vs 4.52x).  So it is an option (`smafl fit --median`), not the default.
"""

from __future__ import annotations

import dataclasses

import equinox as eqx
import jax.numpy as jnp

from .. import _config  # noqa: F401
from .._errors import UserInputError
from .._io import register_model
from ._hysteresis import record_model

__all__ = ["MedianOfModels"]


@register_model
class MedianOfModels(eqx.Module):
    """Output = the median, sample by sample, of ``members``' outputs on the same input record.

    Every member must take the same input (e.g. a drive voltage) and give the same output; use an odd number of
    members for a median that is one member's value at each sample.
    """

    members: tuple

    def __check_init__(self):
        if not isinstance(self.members, tuple) or len(self.members) < 2:
            raise UserInputError(f"MedianOfModels needs a tuple of at least 2 models, got {self.members!r}")
        for i, m in enumerate(self.members):
            if not callable(getattr(m, "simulate", None)):
                raise UserInputError(f"MedianOfModels member {i} ({type(m).__name__}) has no simulate(u, dt)")

    def simulate(self, u, dt):
        """Median over the members of their outputs for input record ``u`` sampled every ``dt`` seconds."""
        return jnp.median(jnp.stack([m.simulate(u, dt) for m in self.members]), axis=0)

    def for_record(self, i: int) -> MedianOfModels:
        """Every member as it starts record ``i`` of a joint fit."""
        return dataclasses.replace(self, members=tuple(record_model(m, i) for m in self.members))

    def with_method(self, method: str) -> MedianOfModels:
        """Copy with every member evaluated by ``method`` (members without that option are kept as they are)."""
        return dataclasses.replace(
            self, members=tuple(m.with_method(method) if hasattr(m, "with_method") else m for m in self.members)
        )

    def describe(self) -> list[str]:
        """One line per member, then the members' own lines, for a fit report."""
        lines = [f"median of {len(self.members)} models: " + ", ".join(type(m).__name__ for m in self.members)]
        for i, m in enumerate(self.members):
            lines += [f"member {i}: {line}" for line in (m.describe() if hasattr(m, "describe") else [])]
        return lines
