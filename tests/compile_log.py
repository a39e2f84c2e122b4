"""Test helper: the names of the XLA programs compiled inside a block (for tests that check programs are reused)."""

import contextlib
import logging
import re

import jax


@contextlib.contextmanager
def compiled_names():
    """Names of the XLA programs compiled inside the block (JAX's compile log)."""
    names = []

    class Grab(logging.Handler):
        def emit(self, record):
            m = re.search(r"Finished XLA compilation of (\S+)", record.getMessage())
            if m:
                names.append(m.group(1))

    logger = logging.getLogger("jax")
    handler, level = Grab(level=logging.DEBUG), logger.level
    logger.addHandler(handler)
    logger.setLevel(logging.DEBUG)
    try:
        with jax.log_compiles(True):
            yield names
    finally:
        logger.removeHandler(handler)
        logger.setLevel(level)
