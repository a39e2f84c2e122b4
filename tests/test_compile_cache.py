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
