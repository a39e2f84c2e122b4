"""Bayesian uncertainty of an identified model: priors, log-posterior, vectorised emcee runs, diagnostics."""

from ._bayes import (
    ChainTooShortWarning,
    Posterior,
    Prior,
    SampleRun,
    check_model_supported,
    default_priors,
    derived_quantities,
    diagnostics,
    linear_modes,
    load_priors,
    load_run,
    resolve_walkers,
    run_sampler,
    summarize,
)

__all__ = [
    "Prior",
    "Posterior",
    "SampleRun",
    "ChainTooShortWarning",
    "default_priors",
    "check_model_supported",
    "linear_modes",
    "resolve_walkers",
    "load_priors",
    "run_sampler",
    "load_run",
    "diagnostics",
    "summarize",
    # Documented helpers that tests and experiments use (issue 12: they import the sub-package API).
    "derived_quantities",
]
