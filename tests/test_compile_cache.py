"""The memory-map guard (`smafl_jax._compile_cache`): a long session must not die at the kernel's map limit."""

import jax
import jax.numpy as jnp
import pytest

import smafl_jax  # noqa: F401  (x64)
from smafl_jax import _compile_cache as cc  # private: white-box test of the map guard; monkeypatch target

linux = pytest.mark.skipif(cc.map_count() is None or cc.map_limit() is None, reason="needs /proc (Linux)")


@linux
def test_guard_clears_the_compiled_programs_only_above_its_threshold():
    f = jax.jit(lambda x: jnp.sin(x) * 2.0)
    for n in range(1, 40):  # 39 shapes: 39 executables, each mapped into memory
        f(jnp.ones(n))
    held = cc.map_count()
    assert cc.release_if_needed(fraction=1.0) is False  # far below the limit: nothing cleared
    assert cc.map_count() >= held - 50
    assert cc.release_if_needed(fraction=0.0) is True  # any count is above 0: cleared
    assert cc.map_count() < held  # the executables were unmapped
    assert float(f(jnp.ones(3))[0]) == pytest.approx(2.0 * float(jnp.sin(1.0)))  # still works (recompiled)


def test_guard_is_a_no_op_where_the_platform_does_not_say(monkeypatch, tmp_path):
    monkeypatch.setattr(cc, "_MAPS", tmp_path / "missing")
    assert cc.map_count() is None and cc.release_if_needed(fraction=0.0) is False


# -- the on-disk cache of compiled programs that the command line turns on -------------------------------------------


def _fit_cli(tmp_path, rec, out, cache):
    import json
    import os
    import subprocess
    import sys

    env = dict(os.environ, SMAFL_COMPILE_CACHE=str(cache), XDG_CACHE_HOME=str(tmp_path / "xdg"), OPENBLAS_NUM_THREADS="1")
    cmd = [sys.executable, "-m", "smafl_jax", "fit", str(rec), "--model", "cascade", "--max-steps", "20", "--no-figures"]
    p = subprocess.run([*cmd, "--out", str(out)], env=env, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr[-2000:]
    return json.loads((out / "fit.json").read_text())


def test_enabled_cache_stores_compiled_programs(tmp_path):
    """Fast check (a subprocess: the cache is process-wide): the folder from the variable receives the programs."""
    import os
    import subprocess
    import sys

    code = (
        "import jax, jax.numpy as jnp; from smafl_jax import _compile_cache as cc; d = cc.enable_persistent_cache(); "
        "jax.config.update('jax_persistent_cache_min_compile_time_secs', 0.0); "
        "print(d); print(float(jax.jit(lambda x: jnp.cumsum(jnp.sin(x)))(jnp.ones(7))[-1]))"
    )
    env = dict(os.environ, SMAFL_COMPILE_CACHE=str(tmp_path / "c"), JAX_PLATFORMS="cpu")
    p = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr[-2000:]
    assert p.stdout.splitlines()[0] == str(tmp_path / "c")
    assert any((tmp_path / "c").iterdir())


@pytest.mark.slow
def test_cli_keeps_compiled_programs_on_disk_and_a_warm_run_gives_the_same_fit(tmp_path):
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).parent))
    import indep_plant

    rec = tmp_path / "rec.csv"
    indep_plant.write_csv(rec, indep_plant.make_record(3, drive="pwm", rate_hz=10, minutes=2.0, start="cold"))
    cache = tmp_path / "cache"
    cold = _fit_cli(tmp_path, rec, tmp_path / "cold", cache)
    stored = sorted(p.name for p in cache.iterdir())
    assert stored, "nothing was written to the cache folder"
    warm = _fit_cli(tmp_path, rec, tmp_path / "warm", cache)
    assert warm["model"] == cold["model"] and warm["metrics"] == cold["metrics"]
    assert not (tmp_path / "xdg").exists()  # the folder the variable names, not the default one
    off = _fit_cli(tmp_path, rec, tmp_path / "off", "off")
    assert off["model"] == cold["model"]  # the same programs with or without the cache (and the LM's step count)
    assert not (tmp_path / "xdg").exists()


def test_cache_off_and_unwritable_folders_leave_jax_alone(monkeypatch, tmp_path):
    # JAX's own setting, not `persistent_cache_dir` (conftest makes the library answer None: the suite shares a folder)
    before = jax.config.jax_compilation_cache_dir
    monkeypatch.setenv(cc.CACHE_ENV, "off")
    assert cc.enable_persistent_cache() is None and jax.config.jax_compilation_cache_dir == before
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    monkeypatch.setenv(cc.CACHE_ENV, str(blocker / "cache"))
    assert cc.enable_persistent_cache() is None and jax.config.jax_compilation_cache_dir == before
