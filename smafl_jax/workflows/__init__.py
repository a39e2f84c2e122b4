"""Library workflows: whole analyses as functions that take Python objects and return results.

The ``smafl`` commands are thin layers over these (parse arguments, call, print);
the paper calls them directly.  Each workflow logs with `logging` and never prints.
"""

from .sample import SamplingResult, sample_posterior

__all__ = ["SamplingResult", "sample_posterior"]
