"""Option values shared by the library and the command line, in a module that imports nothing heavy.

`smafl fit --help` builds its parser from these; importing them from the modules that use them would
import JAX first (seconds), which `--help` should not pay.
"""

#: Joint-refinement solvers of `smafl_jax.fit`.
SOLVERS = ("lm", "gauss_newton", "bfgs", "lbfgsb", "projected_gradient")
#: Model structures `smafl fit --model` accepts.
MODELS = ("auto", "eupi", "cascade", "joule")
#: Validation split rules of one record.
SPLITS = ("auto", "time", "branch", "none")
