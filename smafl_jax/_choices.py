"""Option values shared by the library and the command line, in a module that imports nothing heavy.

`smafl fit --help` builds its parser from these; importing them from the modules that use them would
import JAX first (seconds), which `--help` should not pay.
"""

#: Joint-refinement solvers of `smafl_jax.fit`; "varpro": LM over the nonlinear parameters with the gains solved exactly
#: at every point (`smafl_jax.identify._varpro_refine`).
SOLVERS = ("lm", "gauss_newton", "bfgs", "lbfgsb", "projected_gradient", "varpro")
#: Registry of the hysteresis models (`smafl_jax.models._hysteresis.AbstractHysteresis`): CLI name -> "module:class".
#: A new hysteresis model is one class in one module plus one line here (`smafl fit --model NAME`).
HYSTERESIS = {
    "eupi": "models._eupi:EUPI",
    "preisach": "models._preisach:Preisach",
    "preisach-gauss": "models._preisach_gauss:GaussianPreisach",
    "phase": "models._phase_fraction:PhaseFraction",
}
#: Model structures `smafl fit --model` accepts.
#: ``cascade`` is the Joule cascade with the EUPI (the paper's); ``cascade-NAME`` puts another registered hysteresis class
#: behind the same thermal lag.
MODELS = (
    "auto",
    "eupi",
    "cascade",
    "joule",
    *(k for k in HYSTERESIS if k != "eupi"),
    *(f"cascade-{k}" for k in HYSTERESIS if k != "eupi"),
)
#: Validation split rules of one record.
SPLITS = ("auto", "time", "branch", "interleaved", "none")
#: Operator-memory options of `smafl fit --memory`: "auto", "fitted", "rule" and the initial-state rules a fit
#: screens (the union of the registered models' `AbstractHysteresis.RULE_INITS`; a test checks it).
MEMORY = ("auto", "fitted", "rule", "descended", "zero", "from_top")
#: kappa of the prior on the operator gains in `smafl fit` / `fit_record` / `fit_records` (`smafl_jax.identify._gain_prior`):
#: one operator is expected to move the output by at most about the output's own observed range.
GAIN_PRIOR = 1.0
#: ``hold_input`` of `smafl fit` / `fit_record` / `fit_records` (`smafl_jax.identify._hold`): "auto" (a model that sees
#: its measured input directly; a cascade's thermal state below its trained range), "on" (a cascade's thermal state on
#: both sides), "off" (none: every model extrapolates).
HOLD_INPUT = ("auto", "on", "off")
#: ``slow_mode`` of `smafl fit` / `fit_record`: "auto" tries a slow thermal mode when the kept fit leaves structure on
#: the record it was fitted on (`smafl_jax.report._report_fit._slow_mode_check`), "on" fits every cascade with one, "off"
#: never.
SLOW_MODES = ("auto", "on", "off")
