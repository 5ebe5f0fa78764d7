"""Test configuration: float64, strict promotion, LLVM -O0, persistent compile cache,
fixtures.

JAX compiles are the slow part of this suite on small CI machines: tests share model
*structures* (a jitted sorojax function compiles once per structure, whatever the
parameter values), and the persistent compilation cache keeps compiled programs
between runs on the same machine. The statics entry point keeps host callbacks
out of its compiled core so that it can be cached.
"""

import gc
import importlib.metadata
import os
import pathlib

# LLVM at -O0 for the test programs, set before JAX starts its CPU backend: the same
# HLO programs (XLA's graph passes, fusion and arithmetic are unchanged) compile in
# about half the time and run 2-6x slower, which a compile-bound suite gains from
# (empty-cache run 540 -> 381 s on 2 cores). tests/test_jit.py checks that programs
# compiled at XLA's default level give the same results. SOROJAX_TEST_XLA_OPT=default
# keeps XLA's default level (and sorojax's default compile tiers). With every program
# at -O0 already, sorojax's tiers would only compile a hot program a second time at
# the same level: SOROJAX_COMPILE=full (tests/test_jit.py tests the tiers).
if os.environ.get("SOROJAX_TEST_XLA_OPT", "0") != "default":
    os.environ["XLA_FLAGS"] = " ".join(
        [os.environ.get("XLA_FLAGS", ""), "--xla_backend_optimization_level=0"]
    ).strip()
    os.environ["SOROJAX_COMPILE"] = "full"

# sorojax compiles its own programs with its CPU options (sorojax.compiler_options():
# XLA's classic emitters, 20-35% faster compiles, and matrix products on the calling
# thread, same arithmetic); the tests' own jax.jit programs (gradient checks, vmaps,
# references) get them too: set as flags, on the jaxlib line where the options are
# verified (an unknown XLA flag is fatal). tests/test_jit.py compiles with XLA's
# defaults explicitly to compare. (A gradient check through simulate: 16.5 -> 12.3 s.)
if importlib.metadata.version("jaxlib").startswith("0.10."):
    os.environ["XLA_FLAGS"] = " ".join(
        [
            os.environ.get("XLA_FLAGS", ""),
            "--xla_cpu_use_fusion_emitters=false",
            "--xla_cpu_multi_thread_eigen=false",
        ]
    ).strip()
# And sorojax's runtime flags, as the examples set them (before JAX's backend starts).
import sorojax  # noqa: E402

sorojax.set_runtime_flags()

import jax  # noqa: E402
import pytest  # noqa: E402

jax.config.update("jax_enable_x64", True)
jax.config.update("jax_numpy_dtype_promotion", "strict")
jax.config.update("jax_numpy_rank_promotion", "raise")
# Per-user cache (shared by clones on one machine); keys hash the compiled program, so
# stale entries are never used. Override with SOROJAX_TEST_JAX_CACHE. An empty
# XDG_CACHE_HOME counts as unset (as the XDG spec and sorojax's own cache say).
_xdg = os.environ.get("XDG_CACHE_HOME") or str(pathlib.Path.home() / ".cache")
_cache = os.environ.get(
    "SOROJAX_TEST_JAX_CACHE", str(pathlib.Path(_xdg) / "sorojax" / "jax-tests")
)
jax.config.update("jax_compilation_cache_dir", _cache)
jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.5)
jax.config.update("jax_persistent_cache_min_entry_size_bytes", -1)


# Heaviest test files first (seconds of an empty-cache run on 2 cores): with
# ``--dist loadfile --no-loadscope-reorder`` (pyproject.toml) the two workers take the
# files in this order, each the next one when it is free, so that no long file is
# left to run alone at the end. Unlisted files follow in their own order.
_HEAVY_FIRST = (
    "test_contact.py",  # 83 s
    "test_docs.py",  # 74
    "test_docs_pages.py",  # 54
    "test_closed_loops.py",  # 46
    "test_fixed_step.py",  # 42
    "test_statics.py",  # 42
    "test_dynamics.py",  # 39
    "test_rosenbrock.py",  # 39
    "test_actuation.py",  # 37
    "test_contact_kernels.py",  # 37
    "test_jit.py",  # 33
    "test_adequacy.py",  # 33
    "test_integrate.py",  # 33
    "test_size_class.py",  # 31
    "test_example_learn.py",  # 31
    "test_example_design.py",  # 30
    "test_env.py",  # 29
    "test_example_identification.py",  # 23
    "test_kinematics.py",  # 23
    "test_examples.py",  # 23
    "test_lie.py",  # 19
)


def pytest_collection_modifyitems(config, items):
    """Order the files as ``_HEAVY_FIRST`` (stable: tests keep their order)."""
    rank = {name: i for i, name in enumerate(_HEAVY_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))


@pytest.fixture
def compiles(monkeypatch):
    """The compiler options of every program sorojax's entry points compile, in
    order (one per model structure and tier): a spy on equinox's compile call."""
    from sorojax import _jit as sjit

    seen = []
    real = sjit.eqx._compile_utils.Lowered.compile

    def spy(self, compiler_options=None):
        seen.append(dict(compiler_options or {}))
        return real(self, compiler_options)

    monkeypatch.setattr(sjit.eqx._compile_utils.Lowered, "compile", spy)
    return seen


_EVENTS = {
    "trace": "/jax/core/compile/jaxpr_trace_duration",
    "lower": "/jax/core/compile/jaxpr_to_mlir_module_duration",
    "compile": "/jax/core/compile/backend_compile_duration",
}


@pytest.fixture
def jax_events():
    """``with jax_events("compile") as names:`` collects the function names of JAX's
    events of that kind ("trace", "lower" or "compile": ``jax._src.monitoring``)
    while the block runs."""
    import contextlib

    from jax._src import monitoring

    @contextlib.contextmanager
    def collect(kind):
        names = []

        def listen(event, seconds, **kwargs):
            if event == _EVENTS[kind]:
                names.append(kwargs.get("fun_name", "?"))

        monitoring.register_event_duration_secs_listener(listen)
        try:
            yield names
        finally:
            monitoring.unregister_event_duration_listener(listen)

    return collect


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


@pytest.fixture(scope="session")
def jit_optimised():
    """``eqx.filter_jit`` at XLA's default LLVM level (-O2), for the suite's few
    run-heavy programs (long, tight-tolerance integrations): they compile slower and
    run 2-6x faster than at the suite's -O0."""
    import equinox as eqx

    import sorojax as sj

    opts = {**sj.compiler_options(), "xla_backend_optimization_level": 2}
    return lambda fun: eqx.filter_jit(fun, compiler_options=opts)


@pytest.fixture
def examples_optimised(monkeypatch):
    """``sorojax.compiler_options()`` with XLA's default LLVM level (-O2) for the
    test's duration: an example script's own programs (built with it) then compile
    as :func:`jit_optimised`'s do. For a run-heavy example (the identification's
    trajectory-and-Jacobian program, called some 15 times: the test 16 -> 12 s on
    2 cores from an empty cache)."""
    import sorojax as sj

    plain = sj.compiler_options

    def optimised(long_run: bool = False):
        return {**plain(long_run), "xla_backend_optimization_level": 2}

    monkeypatch.setattr(sj, "compiler_options", optimised)
