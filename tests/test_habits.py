"""Library habits (issue 12): no print in the library, silent unless asked, version from the package
metadata, and the hot posterior log-density traced once (counted by equinox, not by production code)."""

import ast
import contextlib
import importlib.metadata
import logging
import tomllib
from pathlib import Path

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import pytest

import smafl_jax as sj
from smafl_jax import _progress  # private: the progress logger's state (top-level, no public path)

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "smafl_jax"

# Where printing is the job: the command line prints, and the progress logger's stderr handler (and the
# explicit ``stream=`` of `Steps` / `heartbeat`) write the lines the library logs.
PRINT_ALLOWED = ("cli/", "_progress.py")


def _writes_to_console(path):
    """Line numbers of ``print(...)`` calls and ``sys.stdout/stderr.write(...)`` in one source file."""
    lines = []
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if not isinstance(node, ast.Call):
            continue
        f = node.func
        if isinstance(f, ast.Name) and f.id == "print":
            lines.append(node.lineno)
        elif (
            isinstance(f, ast.Attribute)
            and f.attr == "write"
            and isinstance(f.value, ast.Attribute)
            and f.value.attr in ("stdout", "stderr")
        ):
            lines.append(node.lineno)
    return lines


def test_the_library_does_not_print():
    files = sorted(PACKAGE.rglob("*.py"))
    assert len(files) > 50  # the scan sees the package
    found = {}
    for path in files:
        rel = path.relative_to(PACKAGE).as_posix()
        if rel.startswith(PRINT_ALLOWED):
            continue
        if lines := _writes_to_console(path):
            found[rel] = lines
    assert not found, f"library code prints (log through `logging` instead): {found}"
    # the scan finds what it looks for
    assert _writes_to_console(PACKAGE / "_progress.py") and _writes_to_console(PACKAGE / "cli" / "__init__.py")


def _small_problem():
    """A short reversal record of a known EUPI: the fit is the linear initialiser plus a few LM steps."""
    rng = np.random.default_rng(3)
    base = sj.EUPI.from_range(0.0, 5.0, n_sym=4, n_alpha=2, n_asym=2, poly_order=2)
    u = np.clip(np.cumsum(rng.normal(0.0, 0.4, 150)) % 10.0, 0.0, None)
    u = np.where(u > 5.0, 10.0 - u, u)
    y = np.asarray(base.simulate(u)) + 0.01 * rng.standard_normal(u.size)
    return base, (u, y)


@contextlib.contextmanager
def _unconfigured_logging():
    """A program that did not configure logging: pytest's capture handlers are set aside while the block runs."""
    root = logging.getLogger()
    saved = root.handlers
    root.handlers = []
    try:
        yield
    finally:
        root.handlers = saved


def test_the_library_is_silent_unless_asked_and_shows_progress_when_asked(capsys):
    base, data = _small_problem()
    assert _progress.LOGGER.level == logging.NOTSET and not _progress.LOGGER.handlers
    with _unconfigured_logging():
        quiet = sj.fit(base, data, dt=1.0, max_steps=3, progress=False)
        assert capsys.readouterr() == ("", "")
        loud = sj.fit(base, data, dt=1.0, max_steps=3, progress=True)
        out, err = capsys.readouterr()
        assert out == ""
        assert "initialiser: bounded least squares for the gains" in err and "joint refinement: lm, up to 3 steps" in err
        assert loud.loss == quiet.loss  # showing progress changes nothing else
        # the progress logger is left as it was found: later library calls are silent again
        assert _progress.LOGGER.level == logging.NOTSET and not _progress.LOGGER.handlers
        _progress.LOGGER.info("not shown")
        assert capsys.readouterr() == ("", "")


def test_progress_goes_to_the_configured_logging(caplog, capsys):
    base, data = _small_problem()
    with caplog.at_level(logging.INFO):
        sj.fit(base, data, dt=1.0, max_steps=3, progress=False)
    assert not [r for r in caplog.records if r.name == _progress.LOGGER.name]
    # progress=True shows progress even where logging is configured for warnings only (the root logger's level)
    assert logging.getLogger().getEffectiveLevel() == logging.WARNING
    sj.fit(base, data, dt=1.0, max_steps=3, progress=True)
    msgs = [r.getMessage() for r in caplog.records if r.name == _progress.LOGGER.name]
    assert "joint refinement: lm, up to 3 steps" in msgs
    assert capsys.readouterr().err == ""  # shown by the configured handlers, not printed a second time
    # a level the user (or `smafl ... --quiet`) set on the progress logger is respected
    caplog.clear()
    _progress.LOGGER.setLevel(logging.WARNING)
    try:
        sj.fit(base, data, dt=1.0, max_steps=3, progress=True)
    finally:
        _progress.LOGGER.setLevel(logging.NOTSET)
    assert not [r for r in caplog.records if r.name == _progress.LOGGER.name]


def test_the_command_line_shows_library_notes_even_when_quiet(capsys):
    note = logging.getLogger("smafl_jax.bayes._bayes")
    with _progress.shown_on_stderr(False):
        note.warning("resuming chain.h5 at step 3 of 5")
        _progress.LOGGER.info("  phase: 1/2")
    with _progress.shown_on_stderr(True):
        _progress.LOGGER.info("  phase: 2/2")
    err = capsys.readouterr().err
    assert err.splitlines() == ["resuming chain.h5 at step 3 of 5", "  phase: 2/2"]  # as written, once each
    assert not any(isinstance(h, _progress._StderrHandler) for h in logging.getLogger("smafl_jax").handlers)


def test_version_comes_from_the_package_metadata(capsys, monkeypatch):
    from smafl_jax.cli import main

    installed = importlib.metadata.version("smafl-jax")
    assert sj.__version__ == installed
    with pytest.raises(SystemExit) as exit_:
        main(["--version"])
    assert exit_.value.code == 0 and capsys.readouterr().out.strip() == f"smafl {installed}"
    # a source tree that is not installed: the version of pyproject.toml
    with open(ROOT / "pyproject.toml", "rb") as f:
        declared = tomllib.load(f)["project"]["version"]

    def not_installed(name):
        raise importlib.metadata.PackageNotFoundError(name)

    monkeypatch.setattr(importlib.metadata, "version", not_installed)
    assert sj._package_version() == declared


def test_posterior_log_density_traces_once():
    from smafl_jax.bayes._bayes import _log_prob_traced  # private: trace count of the jitted log-density

    rng = np.random.default_rng(0)
    n, dt = 173, 0.5  # a record length no other test uses: the first call must trace
    u = np.zeros(n)
    u[20:], u[90:] = 5.0, 2.0
    truth = sj.JouleThermal(k1=jnp.asarray(0.0625), k2=jnp.asarray(0.055))
    y = np.asarray(truth.simulate(u, dt)) + 0.05 * rng.standard_normal(n)
    post = sj.Posterior(truth, (u, y), dt)
    thetas = post.theta0 + 0.01 * rng.standard_normal((6, post.ndim))
    before = eqx.debug.get_num_traces(_log_prob_traced)
    first = post(thetas)
    assert eqx.debug.get_num_traces(_log_prob_traced) == before + 1
    for shift in (0.1, -0.1, 0.2):  # new values, same shapes: no retrace
        assert np.all(np.isfinite(post(thetas + shift)))
    assert eqx.debug.get_num_traces(_log_prob_traced) == before + 1
    np.testing.assert_allclose(first, [float(post.log_prob(t)) for t in thetas], rtol=1e-12)
    post(thetas[:3])  # another walker count is another shape: one more trace
    assert eqx.debug.get_num_traces(_log_prob_traced) == before + 2
