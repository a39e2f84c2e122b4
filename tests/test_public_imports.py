"""Tests, experiments and benchmarks use the public API (issue 12): `smafl_jax` or a sub-package's `__all__`.

A private module (`smafl_jax._io`, `smafl_jax.diagnosis._diagnose`) or a private name (`_segment`) may be
imported only on a line that says why with a ``# private: <why>`` comment (a monkeypatch target, a white-box
test of a helper).  The sub-packages' `__all__` must resolve, and `smafl_jax.__all__` must not change by
accident: `PUBLIC_API` is its content when the imports were moved to the public paths.
"""

import ast
import importlib
import pkgutil
from pathlib import Path

import pytest

import smafl_jax

ROOT = Path(__file__).resolve().parents[1]
SCANNED = ("tests", "experiments", "benchmarks")
MARKER = "# private:"

#: `smafl_jax.__all__` (sorted): change it here, on purpose, when the top-level API changes.
PUBLIC_API = (
    "AbstractHysteresis", "Cascade", "ChainTooShortWarning", "ClosedLoop", "ControlResult", "ControlSweepResult",
    "DataError", "Diagnosis", "EFFECTS", "EFFECT_NAMES", "EUPI", "ExtendedModel", "FitResult", "GaussianPreisach",
    "IICompensator",
    "JouleLag", "JouleThermal", "PAPER_K1", "PAPER_K2", "PID", "POSITIVE_FLOOR", "PhaseFraction", "Posterior", "Preisach",
    "Prior",
    "Recalibrated", "Record", "SOLVERS", "SampleRun", "StallStop", "SamplingResult", "SimulationResult", "SweepResult",
    "UserInputError", "as_fit_data", "atomic_savefig", "atomic_write_csv", "atomic_write_json", "atomic_write_text",
    "choose_model_method", "closed_loop_metrics", "consistent_initial_state", "constrain", "default_priors",
    "default_trainable", "diagnose", "diagnose_records", "RecordsDiagnosis", "diagnostics", "e_mean", "effective_voltage", "error_ratio",
    "estimate_initial_state", "file_sha256", "fit", "fit_many", "fit_records", "hysteresis_of", "init_linear",
    "init_profile", "initialize_from_env", "load_model", "load_model_file", "load_priors", "load_record", "load_run",
    "log_jacobian", "max_abs_error", "mean_abs_error", "metrics", "model_from_dict", "model_to_dict", "noise_floor", "search_memory", "MedianOfModels",
    "model_with_method", "parameter", "play", "play_assoc", "play_scan", "play_step", "play_weighted", "positive",
    "positive_mask", "prepare_out_dir", "recalibrate", "register_model", "rmse", "run_control", "run_sampler",
    "run_sweep", "sample_posterior", "save_model", "simulate", "simulate_batch", "simulate_closed_loop",
    "simulate_record", "sine_reference", "split_masks", "stack_models", "step_reference", "summarize", "sweep",
    "thermal_of", "thermal_step", "threshold_grid", "tilt_grid", "to_jsonable", "unconstrain", "with_initial_state",
)  # fmt: skip


def _private(part):
    return part.startswith("_") and not (part.startswith("__") and part.endswith("__"))


def private_imports(source, name="<source>"):
    """``["name:line: statement", ...]``: imports of a private smafl_jax module or name without the marker."""
    lines = source.splitlines()
    found = []
    for node in ast.walk(ast.parse(source, filename=name)):
        if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            parts = node.module.split(".")
            bad = parts[0] == "smafl_jax" and (any(_private(p) for p in parts[1:]) or any(_private(a.name) for a in node.names))
        elif isinstance(node, ast.Import):
            bad = any(a.name.split(".")[0] == "smafl_jax" and any(_private(p) for p in a.name.split(".")[1:]) for a in node.names)
        else:
            continue
        span = lines[node.lineno - 1 : node.end_lineno]
        if bad and not any(MARKER in line for line in span):
            found.append(f"{name}:{node.lineno}: {span[0].strip()}")
    return found


def test_scanner_finds_private_imports_and_respects_the_marker():
    src = (
        "import smafl_jax\n"
        "from smafl_jax.identify import fit\n"
        "from smafl_jax import __version__\n"
        "from smafl_jax.diagnosis._diagnose import make_split\n"
        "from smafl_jax import _io\n"
        "import smafl_jax.ops._play as p\n"
        "def f():\n"
        "    from smafl_jax.data.split import _directions\n"
        "    from smafl_jax.identify import _fit  # private: monkeypatch target\n"
        "from smafl_jax.diagnosis._diagnose import (  # private: white-box\n"
        "    _get_phi,\n"
        ")\n"
    )
    assert [s.split(":")[1] for s in private_imports(src)] == ["4", "5", "6", "8"]


def test_tests_experiments_and_benchmarks_import_the_public_api():
    found = []
    for folder in SCANNED:
        for path in sorted((ROOT / folder).rglob("*.py")):
            found += private_imports(path.read_text(encoding="utf-8"), str(path.relative_to(ROOT)))
    assert not found, (
        "private smafl_jax imports: use `smafl_jax` or the sub-package's __all__ (export the name there), or say why "
        f"with `{MARKER} <why>` on the line:\n" + "\n".join(found)
    )


def _subpackages():
    return sorted(m.name for m in pkgutil.iter_modules(smafl_jax.__path__) if m.ispkg)


def test_the_scan_covers_the_sub_packages():
    assert {"models", "identify", "effects", "bayes", "control", "diagnosis", "report", "data", "ops"} <= set(_subpackages())


@pytest.mark.parametrize("sub", _subpackages())
def test_every_name_of_a_sub_package_all_is_importable(sub):
    mod = importlib.import_module(f"smafl_jax.{sub}")
    names = list(getattr(mod, "__all__", ()))
    assert len(names) == len(set(names)), f"duplicates in smafl_jax.{sub}.__all__"
    missing = [n for n in names if not hasattr(mod, n)]
    assert not missing, f"smafl_jax.{sub}.__all__ names what it does not define: {missing}"
    ns = {}
    exec(f"from smafl_jax.{sub} import *", ns)  # the star import a user may write
    assert set(names) <= set(ns)


def test_top_level_all_is_unchanged_and_resolves():
    now = set(smafl_jax.__all__)
    assert len(smafl_jax.__all__) == len(now), "duplicates in smafl_jax.__all__"
    assert now == set(PUBLIC_API), (
        f"smafl_jax.__all__ changed: removed {sorted(set(PUBLIC_API) - now)}, added {sorted(now - set(PUBLIC_API))} "
        "(update PUBLIC_API only for an intended API change)"
    )
    missing = [n for n in PUBLIC_API if not hasattr(smafl_jax, n)]
    assert not missing, missing
