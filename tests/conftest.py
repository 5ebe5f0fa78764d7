"""Test configuration: float64, strict promotion, persistent compile cache, fixtures.

JAX compiles are the slow part of this suite on small CI machines: tests share model
*structures* (a jitted sorojax function compiles once per structure, whatever the
parameter values), and the persistent compilation cache keeps compiled programs
between runs on the same machine. The statics entry point keeps host callbacks
out of its compiled core so that it can be cached.
"""

import gc
import os
import pathlib

import jax
import pytest

jax.config.update("jax_enable_x64", True)
jax.config.update("jax_numpy_dtype_promotion", "strict")
jax.config.update("jax_numpy_rank_promotion", "raise")
# Per-user cache (shared by clones on one machine); keys hash the compiled program, so
# stale entries are never used. Override with SOROJAX_TEST_JAX_CACHE.
_xdg = os.environ.get("XDG_CACHE_HOME", str(pathlib.Path.home() / ".cache"))
_cache = os.environ.get(
    "SOROJAX_TEST_JAX_CACHE", str(pathlib.Path(_xdg) / "sorojax" / "jax-tests")
)
jax.config.update("jax_compilation_cache_dir", _cache)
jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.5)
jax.config.update("jax_persistent_cache_min_entry_size_bytes", -1)


@pytest.fixture
def key():
    """A fixed PRNG key."""
    return jax.random.PRNGKey(0)


@pytest.fixture(autouse=True, scope="module")
def _release_compiled_programs():
    """Drop JAX's in-memory compiled programs after each test module.

    Long single-process runs that compile hundreds of large programs (closed-loop
    statics, dynamics) crashed inside XLA's compiler (segmentation fault) on the
    2-core machine; releasing them per module (the persistent cache still serves
    repeats) and splitting the files over two pytest-xdist workers (``-n 2 --dist
    loadfile`` in pyproject.toml) keeps each process small.
    """
    yield
    jax.clear_caches()
    gc.collect()
