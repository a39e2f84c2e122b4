"""Strict JAX settings for every test: float64 and no implicit rank promotion."""

import os
import shutil
import tempfile
from pathlib import Path

import jax
import pytest
import scipy.linalg  # noqa: F401  (loads scipy's own OpenBLAS copy, so that the limit below reaches it too)
from threadpoolctl import threadpool_limits

# One BLAS thread per test process: `pytest -n 2` runs two processes on the two cores, and two busy-waiting OpenBLAS
# pools each the size of the machine compete for them (the timings in .notes/session12_note.md were taken with one
# thread).  Set through threadpoolctl because a pytest plugin has already loaded numpy (and OpenBLAS) when this file
# runs, so the environment variable would come too late.
BLAS_LIMIT = threadpool_limits(limits=1, user_api="blas")

jax.config.update("jax_enable_x64", True)
jax.config.update("jax_numpy_rank_promotion", "raise")
# the command line keeps compiled programs on disk (`_compile_cache.enable_persistent_cache`); tests that run it in
# this process must not write to the user's cache folder nor change how later tests compile (test_compile_cache.py
# runs it in subprocesses with a folder of its own)
os.environ["SMAFL_COMPILE_CACHE"] = "off"

#: Folder of compiled programs shared by the test processes of one run ("off" to compile everything afresh).
TEST_XLA_CACHE = "SMAFL_TEST_XLA_CACHE"


def pytest_configure(config):
    """Share compiled programs between the test processes of one run (suite time, session 71: about 13 % less on two
    subsets of the suite under `pytest -n 2`): the controller makes a fresh folder, `pytest -n` workers inherit it.

    Nothing a test observes changes but compile time: the library is told no cache is set (`persistent_cache_dir`
    answers None), so its fits take their default path (steps counted through a host callback; JAX does not store
    such programs), and a program read from the folder is the one XLA compiled for the same module earlier in the run.
    """
    if not hasattr(config, "workerinput") and TEST_XLA_CACHE not in os.environ:
        config._smafl_xla_cache = tempfile.mkdtemp(prefix="smafl-test-xla-")
        os.environ[TEST_XLA_CACHE] = config._smafl_xla_cache
    where = os.environ.get(TEST_XLA_CACHE, "off")
    if where == "off":
        return
    from smafl_jax import _compile_cache  # private: the library must answer as without a cache (see above)
    from smafl_jax.identify import _fit  # private: it imported `persistent_cache_dir` by name

    jax.config.update("jax_compilation_cache_dir", where)
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    for module in (_compile_cache, _fit):
        module.persistent_cache_dir = lambda: None


def pytest_unconfigure(config):
    if getattr(config, "_smafl_xla_cache", None):
        shutil.rmtree(config._smafl_xla_cache, ignore_errors=True)


ROOT = Path(__file__).resolve().parents[1]
REAL_DATA = ROOT.parent / "shared" / "data" / "real"
DATASETS = ROOT / "datasets"


@pytest.fixture
def real_data():
    """Folder of real measured records (read in place); skip when a fresh clone lacks it."""
    path = Path(os.environ.get("SMAFL_REAL_DATA", REAL_DATA))
    if not path.is_dir():
        pytest.skip(f"real data folder {path} not present (it lives beside the repo in ../shared/data/real)")
    return path


@pytest.fixture
def datasets_dir():
    return DATASETS


@pytest.fixture
def rng():
    import numpy as np

    return np.random.default_rng(1234)


@pytest.fixture(scope="module")
def short_indep_record(tmp_path_factory):
    """A 2-minute cold multisine record at 10 Hz from the independent numpy plant (tests/indep_plant.py), loaded from
    CSV as a user's file is: for tests of the fitting machinery that need a real-looking record, not a particular one."""
    import sys

    import smafl_jax as sj

    sys.path.insert(0, str(Path(__file__).parent))
    import indep_plant

    r = indep_plant.make_record(3, drive="multisine", rate_hz=10, minutes=2, start="cold")
    path = tmp_path_factory.mktemp("indep") / "rec.csv"
    indep_plant.write_csv(path, r)
    return sj.load_record(path)


def _direct_record_csv(path, seed, input_column, **kw):
    """A steps record of the independent direct-input plant (Preisach) written to ``path`` as a user's CSV
    (``time_s``, ``input_column``, ``displacement_mm``) and loaded; ``kw``: `indep_direct.make_record` options."""
    import sys

    import numpy as np

    import smafl_jax as sj

    sys.path.insert(0, str(Path(__file__).parent))
    import indep_direct

    r = indep_direct.make_record(seed, "preisach", "steps", **kw)
    np.savetxt(path, np.column_stack([r["t"], r["u"], r["y"]]), delimiter=",", header=f"time_s,{input_column},displacement_mm",
               comments="", fmt="%.9g")  # fmt: skip
    return sj.load_record(path)


@pytest.fixture(scope="module")
def stand_in_record(tmp_path_factory):
    """A short voltage-driven record of the direct-input plant (Preisach, steps), loaded as a user would: the record
    behind tests that fit stand-in candidates through `choose_structure`."""
    path = tmp_path_factory.mktemp("stand_in") / "v.csv"
    return _direct_record_csv(path, 6, "voltage_V", n=400, dt=0.05, u_lo=0.2, u_span=6.0)


@pytest.fixture(scope="session")
def direct_record_csv():
    """`_direct_record_csv`: ``(path, seed, input_column, **make_record options) -> Record``."""
    return _direct_record_csv
