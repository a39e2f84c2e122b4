"""Process-wide JAX settings the toolkit relies on.

Identification of hysteresis gains is ill-conditioned; float32 loses several
significant digits in the normal equations and in long thermal recurrences, so
the toolkit turns on 64-bit mode as soon as it is imported.
"""

import jax

jax.config.update("jax_enable_x64", True)
