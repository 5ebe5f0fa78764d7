"""sorojax's compiled entry points: XLA options and one trace of the right-hand side.

sorojax compiles its own programs with XLA options of its own
(``sorojax.compiler_options()``: the classic CPU emitters, which compile its many
small kernels faster). They must not change the arithmetic beyond rounding, must
fall back to XLA's defaults when turned off or unknown, and the dynamics' right-hand
side must be traced once per program however often diffrax calls it.
"""

import concurrent.futures
import sys
import time
import warnings

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import sorojax as sj
import sorojax._jit as sjit
import sorojax.integrate._simulate as simulate_module


@pytest.fixture(scope="module")
def arm():
    """A rigid bar on a prescribed revolute joint under gravity, and a soft rod."""
    bar = sj.RigidLink(sj.Joint("R", axis=(0, 0, 1.0)), length=0.3, mass=0.2)
    rod = sj.SoftLink(
        [
            sj.Division(
                0.4, sj.CircularSection(0.01), sj.LegendreBasis((0, 1, 1, 0, 0, 0), 1)
            )
        ],
        sj.Material(1e6, 0.5),
    )
    return sj.Linkage(
        [bar, rod],
        gravity=(0, -9.81, 0),
        actuators=[sj.JointActuator(1, prescribed=True)],
    )


def test_options_are_a_fresh_dict_and_turn_off(monkeypatch):
    """Callers may change the dict they get; ``SOROJAX_XLA_OPTIONS=off`` gives {}."""
    opts = sj.compiler_options()
    assert opts.items() <= sjit.CPU_OPTIONS.items()  # those this XLA knows
    opts["something"] = 1
    assert "something" not in sj.compiler_options()
    sjit._probed_options.cache_clear()
    monkeypatch.setenv("SOROJAX_XLA_OPTIONS", "off")
    try:
        assert sj.compiler_options() == {}
    finally:
        sjit._probed_options.cache_clear()


def test_an_unknown_option_is_dropped_alone(monkeypatch):
    """An XLA that lacks one of the options (a newer jaxlib dropped
    ``xla_cpu_use_fusion_emitters``) keeps the others: each is probed on its own."""
    if jax.default_backend() != "cpu":
        pytest.skip("CPU options")
    known = sj.compiler_options()
    monkeypatch.setattr(
        sjit, "CPU_OPTIONS", {**sjit.CPU_OPTIONS, "xla_cpu_no_such_option": True}
    )
    sjit._probed_options.cache_clear()
    try:
        assert sj.compiler_options() == known
    finally:
        sjit._probed_options.cache_clear()


def test_this_xla_knows_the_options():
    """On the jax 0.10 line (what CI installs today) the options must be in effect
    on CPU: a silent fall back to XLA's defaults would lose the compile-time gain."""
    if jax.default_backend() != "cpu":
        pytest.skip("CPU options")
    if not jax.__version__.startswith("0.10."):  # XLA may drop or rename the option
        pytest.skip(f"the option was verified with jax 0.10; this is {jax.__version__}")
    assert sj.compiler_options() == sjit.CPU_OPTIONS
    long_run = sj.compiler_options(long_run=True)
    assert long_run == {**sjit.CPU_OPTIONS, **sjit.LONG_RUN_OPTIONS}


_RUNTIME_SCRIPT = """
import json, os, sys
import jax
jax.config.update("jax_enable_x64", True)
import numpy as np
import sorojax as sj
out = {"before": os.environ.get("XLA_FLAGS", "")}
os.environ["SOROJAX_XLA_OPTIONS"] = "off"
out["off"] = sj.set_runtime_flags()
del os.environ["SOROJAX_XLA_OPTIONS"]
out["set"] = sj.set_runtime_flags()
out["nproc_default"] = os.environ.get("NPROC")
out["set_threads"] = sj.set_runtime_flags(threads=1)
out["flags"] = os.environ.get("XLA_FLAGS", "")
rod = sj.SoftLink(
    [sj.Division(0.5, sj.CircularSection(0.01), sj.LegendreBasis((0, 1, 1, 0, 0, 0), 1))],
    sj.Material(1e6, 0.5, rho=1000.0),
)
lk = sj.Linkage([rod], gravity=(0.0, 0.0, -9.81))
q = np.linspace(-1.0, 1.0, lk.n_dof)
out["q"] = np.asarray(sj.mass_matrix(lk, q)).tobytes().hex()
out["after_start"] = sj.set_runtime_flags()
out["nproc"] = os.environ.get("NPROC")
if sys.platform == "linux":  # the runtime pool's threads, by name
    tasks = [open(f"/proc/self/task/{t}/comm").read() for t in os.listdir("/proc/self/task")]
    out["pool"] = sum(name.startswith("tf_XLAEigen") for name in tasks)
print(json.dumps(out))
"""


def _run_runtime_script(xla_flags, nproc=None):
    import json
    import os
    import subprocess
    import sys

    env = {
        k: v for k, v in os.environ.items() if k not in ("SOROJAX_XLA_OPTIONS", "NPROC")
    }
    env["XLA_FLAGS"] = xla_flags
    if nproc is not None:
        env["NPROC"] = nproc
    env["SOROJAX_CACHE_DIR"] = "off"
    done = subprocess.run(
        [sys.executable, "-c", _RUNTIME_SCRIPT],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
        check=True,
    )
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_set_runtime_flags_before_the_backend_only_same_results():
    """``set_runtime_flags`` adds its flags to XLA_FLAGS only before JAX's backend
    starts (XLA reads them then), not with SOROJAX_XLA_OPTIONS=off, keeps a value the
    user set, and changes how programs run, not what they compute: a rod's mass
    matrix agrees to rounding (1e-13; the operations' order may change the last
    bits) with the flag and with the user's opposite value (fresh processes: the
    flags are read once per process). Without ``threads`` NPROC is left unset;
    ``threads=1`` sets NPROC=1, XLA's CPU runtime then has one pool thread (the
    user's NPROC=2 is kept: two); /proc's thread names, Linux only."""
    if not jax.__version__.startswith("0.10."):  # the verified jaxlib line
        pytest.skip(f"the flags were verified with jax 0.10; this is {jax.__version__}")
    name = "--xla_cpu_enable_concurrency_optimized_scheduler"
    ours = _run_runtime_script("--xla_backend_optimization_level=0")
    assert ours["off"] is False and ours["set"] is True
    assert ours["flags"] == f"--xla_backend_optimization_level=0 {name}=false"
    assert ours["after_start"] is False  # the backend has started
    level = "--xla_backend_optimization_level=0"
    theirs = _run_runtime_script(f"{level} {name}=true", nproc="2")
    assert theirs["set"] is True and theirs["flags"] == f"{level} {name}=true"  # kept
    assert ours["nproc_default"] is None and ours["set_threads"] is True
    assert ours["nproc"] == "1" and theirs["nproc"] == "2"
    if sys.platform == "linux":  # XLA read NPROC: its pool's threads
        assert (ours["pool"], theirs["pool"]) == (1, 2), (ours["pool"], theirs["pool"])
    a, b = (np.frombuffer(bytes.fromhex(r["q"])) for r in (ours, theirs))
    np.testing.assert_allclose(a, b, rtol=1e-13, atol=1e-15)


@pytest.mark.parametrize("threads", [0, -2, True, 2.5, "2"])
def test_set_runtime_flags_refuses_a_thread_count_not_a_whole_number_from_one(threads):
    """A runtime pool of no thread, or a count that is not a whole number (a bool,
    a float, a string), is refused, naming the argument."""
    with pytest.raises(ValueError, match=r"threads=.*at least 1"):
        sj.set_runtime_flags(threads=threads)


def test_jit_uses_the_options_at_top_level_only(monkeypatch):
    """``sorojax._jit.jit`` compiles top-level calls with the probed options (built
    once, on the first call) and calls inside another trace (jit, grad, vmap) with a
    plain filter_jit: JAX rejects compiler options on nested jits."""
    seen = []
    real = sjit.eqx.filter_jit

    def spy(fun, **kw):
        seen.append(kw)
        return real(fun, **kw)

    monkeypatch.setattr(sjit.eqx, "filter_jit", spy)
    f = sjit.jit(lambda x: 2.0 * x * x)
    assert seen == [{}]  # the plain one; nothing probed at decoration time
    assert float(f(jnp.asarray(1.5))) == 4.5
    assert float(f(jnp.asarray(2.5))) == 12.5
    opts = sj.compiler_options()
    assert seen == ([{}, {"compiler_options": opts}] if opts else [{}])
    assert float(jax.jit(f)(jnp.asarray(1.5))) == 4.5
    assert float(jax.grad(f)(jnp.asarray(1.5))) == 6.0
    np.testing.assert_array_equal(jax.vmap(f)(jnp.arange(3.0)), [0.0, 2.0, 8.0])
    assert len(seen) == (2 if opts else 1)
    # ahead-of-time compilation, as on a filter_jit (the benchmarks time compiles so)
    compiled = f.lower(jnp.asarray(1.0)).compile()
    assert float(compiled(jnp.asarray(3.0))) == 18.0


def test_results_agree_with_xla_default_options(arm):
    """Mass matrix, generalised force and statics compiled with sorojax's options
    equal the same programs under a plain ``jax.jit`` with XLA's defaults (fusion
    emitters on and multi-threaded Eigen products, set explicitly; the mass matrix
    and force also with ``compiler_options(long_run=True)``:
    tests/conftest.py turns both off for the suite's own programs) to rounding:
    1e-12 relative (the options change code generation and threading, not the
    arithmetic)."""
    xla_defaults = {
        "xla_cpu_use_fusion_emitters": True,
        "xla_cpu_multi_thread_eigen": True,
    }
    q = jnp.linspace(-0.3, 0.4, arm.n_dof)
    qd = jnp.linspace(0.2, -0.1, arm.n_dof)

    def terms(q, qd):
        return sj.mass_matrix(arm, q), sj.equations_of_motion(arm, q, qd)[1]

    M0, f0 = terms(q, qd)
    M1, f1 = jax.jit(terms, compiler_options=xla_defaults)(q, qd)
    np.testing.assert_allclose(M0, M1, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(f0, f1, rtol=1e-12, atol=1e-12)
    # and with the long-run options (XLA's YNNPACK fusions off)
    long_run = sj.compiler_options(long_run=True)
    M2, f2 = jax.jit(terms, compiler_options=long_run)(q, qd)
    np.testing.assert_allclose(M0, M2, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(f0, f2, rtol=1e-12, atol=1e-12)

    def statics(th):
        sol = sj.solve_statics(arm, u=jnp.stack([th]))
        return sol.q, sol.efforts

    qs0, e0 = statics(jnp.asarray(0.5))
    qs1, e1 = jax.jit(statics, compiler_options=xla_defaults)(jnp.asarray(0.5))
    np.testing.assert_allclose(qs0, qs1, rtol=1e-10, atol=1e-13)
    np.testing.assert_allclose(e0, e1, rtol=1e-10, atol=1e-13)


def _angle(t):
    """The arm's prescribed angle [rad] in the motions below."""
    return jnp.stack([0.5 + 0.2 * jnp.sin(3.0 * t)])


@pytest.fixture(scope="module")
def arm_motion(arm):
    """``run(th)``: statics at angle ``th``, then 0.2 s of motion from there (ROS34PW2,
    named: "auto" decides from the structure under a jit), and its values at 0.5
    from one program compiled as the suite compiles (-O0)."""

    def run(th):
        sol = sj.solve_statics(arm, u=jnp.stack([th]))
        tr = sj.simulate(
            arm, 0.2, sol.q, u=_angle, n_save=3, solver="ros34pw2", throw=False
        )
        return sol.q, sol.efforts, tr.q, tr.qd, tr.u, tr.efforts

    opts = sj.compiler_options()
    return run, jax.jit(run, compiler_options=opts)(jnp.asarray(0.5))


def test_results_agree_at_xla_default_optimisation_level(arm_motion, jit_optimised):
    """The suite compiles with LLVM at -O0 (tests/conftest.py); users get XLA's
    default level. Statics and 0.2 s of dynamics of the prescribed arm compiled at
    level 2 (``xla_backend_optimization_level``, passed per program) equal the
    suite's -O0 programs: the level changes machine code, not the arithmetic
    (1e-12 relative; measured equal to rounding)."""
    run, in_suite = arm_motion
    at_default = jit_optimised(run)(jnp.asarray(0.5))  # conftest.py: level 2
    for a, b in zip(at_default, in_suite, strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-13)


def test_dynamics_right_hand_side_is_traced_once(arm, monkeypatch):
    """diffrax evaluates the vector field at several places (term check, first
    stage, stage loop) and the efforts at the save points evaluate it again; sorojax
    routes them all through one jitted function, so the (slow, Python) trace of the
    constrained dynamics happens once per program."""
    calls = []
    real = simulate_module.constrained_dynamics

    def counting(*args, **kw):
        calls.append(1)
        return real(*args, **kw)

    monkeypatch.setattr(simulate_module, "constrained_dynamics", counting)
    u = lambda t: jnp.stack([0.3 * jnp.sin(2.0 * t)])  # noqa: E731
    jax.eval_shape(
        lambda: sj.simulate(arm, 0.1, u=u, solver="tsit5", n_save=3, throw=False).q
    )
    # diffrax's term check (an eval_shape with its own abstract arguments) traces
    # it once more; before sharing the trace it was 5 (check, first stage, stage
    # loop twice, save points)
    assert 1 <= len(calls) <= 2, f"constrained dynamics traced {len(calls)} times"


def test_traced_once_inlines_one_trace_into_every_program():
    """A :func:`sorojax._jit.traced_once` function runs its Python once per argument
    structure and shape: later programs (and jvp, vmap, grad of it) reuse the cached
    jaxpr, inlined (no call in the program), with the plain function's values."""
    calls = []

    def body(x, k):
        calls.append(1)
        return jnp.sin(x) * k + jnp.cumsum(x)

    f = sjit.traced_once(body)
    x = jnp.linspace(0.1, 1.0, 5)
    a = jax.make_jaxpr(lambda x: f(x, 2.0) + 1.0)(x)
    jax.make_jaxpr(lambda x: jax.vmap(lambda y: f(y, 2.0))(jnp.stack([x, x])))(x)
    grad = jax.jit(jax.grad(lambda x: jnp.sum(f(x, 2.0) ** 2)))(x)
    assert len(calls) == 1  # one trace for the three programs
    names = [e.params.get("name") for e in a.jaxpr.eqns if "jaxpr" in e.params]
    assert "body" not in names  # inlined: its equations, not a call
    assert "sin" in [e.primitive.name for e in a.jaxpr.eqns]
    plain = jax.grad(lambda x: jnp.sum(body(x, 2.0) ** 2))(x)
    np.testing.assert_allclose(grad, plain, rtol=1e-14)
    jax.make_jaxpr(lambda x: f(x, 3.0))(x)  # a new static value: a new trace
    assert len(calls) == 3  # (the eager plain grad above traced body once more)


def test_a_model_is_precomputed_once_for_all_its_programs(monkeypatch):
    """:func:`sorojax.precompute` (bases, sections, K, D) is traced once per linkage
    structure, not once per program: statics, kinematics and dynamics of one model
    share it. The cache is per structure (shapes and static fields), so a test run
    before this one in the same process may have traced it already: at most once."""
    import sorojax.model._precompute as pre

    calls = []
    real = pre._precompute

    def counting(linkage):
        calls.append(1)
        return real(linkage)

    monkeypatch.setattr(pre, "_precompute", counting)
    rod = sj.SoftLink(
        [
            sj.Division(
                0.37,
                sj.CircularSection(0.011),
                sj.LegendreBasis((0, 1, 0, 0, 0, 0), 2),
                n_gauss=7,
            )
        ],
        sj.Material(2e6, 0.5),
    )
    lk = sj.Linkage([rod], gravity=(0, 0, -9.81))
    q = jnp.zeros(lk.n_dof)
    jax.eval_shape(lambda: sj.solve_statics(lk, q).q)
    jax.eval_shape(lambda: sj.forward_kinematics(lk, q))
    jax.eval_shape(lambda: sj.mass_matrix(lk, q))
    jax.eval_shape(lambda: sj.simulate(lk, 0.1, solver="tsit5", n_save=3).q)
    assert len(calls) <= 1, f"precompute traced {len(calls)} times for 4 programs"


def test_compile_mode_reads_the_environment(monkeypatch):
    """``SOROJAX_COMPILE`` picks the tiers; unset or empty is "tiered"; anything else
    is an error that names the variable, the value and the choices."""
    monkeypatch.delenv("SOROJAX_COMPILE", raising=False)
    assert sj.compile_mode() == "tiered"
    for mode in sjit.MODES:
        monkeypatch.setenv("SOROJAX_COMPILE", f" {mode.upper()} ")
        assert sj.compile_mode() == mode
    monkeypatch.setenv("SOROJAX_COMPILE", "O3")
    with pytest.raises(ValueError, match=r"SOROJAX_COMPILE='o3'.*tiered.*full.*fast"):
        sj.compile_mode()


@pytest.fixture
def tiered(monkeypatch, compiles):
    """The tiered compile mode (the suite runs "full": every program is at -O0),
    with the compile spy of conftest.py."""
    if not sjit._tiers_apply():
        pytest.skip("compile tiers apply on CPU with sorojax's XLA options")
    monkeypatch.setenv("SOROJAX_COMPILE", "tiered")
    return compiles


def test_tiered_program_starts_at_O0_and_is_compiled_again_once_hot(tiered):
    """First call: one trace, compiled with ``xla_backend_optimization_level = 0``.
    The program is recompiled at the default level (sorojax's options without the
    -O0 entry) only once its calls have run for as long as its first compile took
    (the budget; set to zero here to trigger it), in a worker thread while calls
    go on at -O0; once it is done the -O0 program is not used. Same function, same
    values at both tiers."""
    f = sjit.jit(lambda x, n: jnp.cumsum(jnp.sin(x) * n))
    x = jnp.linspace(0.0, 1.0, 5)
    first = f(x, 2)
    assert tiered == [{**sj.compiler_options(), **sjit.FAST_OPTIONS}]
    (program,) = f.programs.values()
    assert program.full is None and program.budget > 0.0 and program.spent > 0.0
    program.budget = program.spent  # as if its calls had run as long as the compile
    second = f(x, 2)  # starts the second compile in a thread, runs the -O0 program
    assert program.promoting is not None and program.full is None
    program.promoting.result()
    assert tiered[1:] == [sj.compiler_options()]
    third = f(x, 2)  # the compile is done: from now on the promoted program
    assert program.full is not None and program.lowered is None
    assert program.promoting is None
    np.testing.assert_allclose(first, second, rtol=0.0)  # the same -O0 program
    np.testing.assert_allclose(first, third, rtol=1e-15)  # both -O0 in this suite
    f(x + 1.0, 2)  # new values: the same (promoted) program, no compile
    f(np.asarray(x), 2)  # a NumPy array is the same argument type to JAX
    assert len(tiered) == 2 and len(f.programs) == 1
    # a new shape, a new static value: a program each, each at -O0 first
    f(jnp.zeros(3), 2)
    f(x, 3)
    assert len(f.programs) == 3 and tiered[2:] == 2 * [tiered[0]]


def test_program_compiled_ahead_in_a_thread_serves_the_call(tiered):
    """``compile_ahead`` traces and compiles (at -O0) the program of a call in a
    worker thread; the call then uses that program (one compile in all) and gives
    the plain function's values. A trace that fails in the thread raises at the
    call, and leaves no program behind."""
    f = sjit.jit(lambda x, n: jnp.cumsum(jnp.cos(x) * n))
    x = jnp.linspace(0.0, 1.0, 7)
    future = f.compile_ahead(jnp.zeros(7), 3)
    assert future is not None
    future.result()
    assert f.compile_ahead(jnp.ones(7), 3) is None  # same signature: nothing new
    np.testing.assert_allclose(f(x, 3), np.cumsum(np.cos(np.asarray(x)) * 3), 1e-14)
    assert tiered == [{**sj.compiler_options(), **sjit.FAST_OPTIONS}]
    assert len(f.programs) == 1

    def bad(x):
        raise KeyError("traced in the thread")

    g = sjit.jit(bad)
    assert g.compile_ahead(x) is not None
    with pytest.raises(KeyError, match="traced in the thread"):
        g(x)
    assert not g.programs


def test_prepare_compiles_the_later_calls_program_in_a_thread(tiered):
    """``sorojax.prepare`` traces and lowers the program of a later call in the
    calling thread and compiles it in a worker thread, in the tier the call would
    use (-O0 for a tiered function, the default level for one that starts there,
    as ``simulate``'s integration): the call then compiles nothing (one compile in
    all per program) and gives the plain function's values. Preparing the same
    signature again does nothing (None)."""
    f = sjit.jit(lambda x, n: jnp.cumsum(jnp.tan(x) * n))
    x = jnp.linspace(0.0, 1.0, 6)
    future = sj.prepare(f, jnp.zeros(6), 4)  # values do not matter, shapes do
    assert future is not None
    assert sj.prepare(f, jnp.ones(6), 4) is None
    future.result()
    np.testing.assert_allclose(f(x, 4), np.cumsum(np.tan(np.asarray(x)) * 4), 1e-14)
    assert tiered == [{**sj.compiler_options(), **sjit.FAST_OPTIONS}]
    (program,) = f.programs.values()  # the -O0 tier, its budget counted as usual
    assert isinstance(program, sjit._TieredProgram) and program.budget > 0.0
    g = sjit.jit(lambda x: jnp.cumprod(x + 1.0), tiered=False)
    future = sj.prepare(g, x)
    assert future is not None and sj.prepare(g, x) is None
    np.testing.assert_allclose(g(x), np.cumprod(np.asarray(x) + 1.0), rtol=1e-14)
    g(x + 1.0)  # new values, same program
    assert tiered[1:] == [sj.compiler_options()]  # at the default level, once
    assert len(g.prepared) == 1


def test_lower_first_traces_now_and_the_call_compiles_that_lowering(tiered, jax_events):
    """``lower_first`` traces and lowers a call's program in the calling thread and
    compiles nothing; the call then compiles that lowering, in its tier (-O0 for a
    tiered function, the default level for one that starts there), without a
    second trace, and gives the plain function's values. The same signature again
    does nothing."""
    f = sjit.jit(lambda x, n: jnp.cumsum(jnp.sinh(x) * n))
    x = jnp.linspace(0.0, 1.0, 5)
    with jax_events("trace") as traced:
        f.lower_first(jnp.zeros(5), 2)  # values do not matter, shapes do
        f.lower_first(jnp.ones(5), 2)
    assert traced.count("<lambda>") == 1 and not tiered
    with jax_events("trace") as traced:
        got = f(x, 2)
    assert "<lambda>" not in traced
    np.testing.assert_allclose(got, np.cumsum(np.sinh(np.asarray(x)) * 2), 1e-14)
    assert tiered == [{**sj.compiler_options(), **sjit.FAST_OPTIONS}]
    (program,) = f.programs.values()
    assert isinstance(program, sjit._TieredProgram) and program.budget > 0.0
    g = sjit.jit(lambda x: jnp.cumprod(x + 1.0), tiered=False)
    g.lower_first(x)
    assert tiered[1:] == []
    np.testing.assert_allclose(g(x), np.cumprod(np.asarray(x) + 1.0), rtol=1e-14)
    g(x + 1.0)  # new values, same program
    assert tiered[1:] == [sj.compiler_options()]  # at the default level, once
    assert len(g.prepared) == 1


def test_prepare_rejects_other_functions_and_does_nothing_in_a_trace(tiered, arm):
    """Only sorojax's entry points and ``sorojax.jit`` functions can be prepared (a
    TypeError names the fix), with the arguments their call takes; inside a user's
    trace there is no program of its own to compile (None, nothing compiled)."""
    with pytest.raises(TypeError, match="sorojax.jit"):
        sj.prepare(jnp.sin, jnp.ones(3))
    with pytest.raises(TypeError, match="n_saves"):
        sj.prepare(sj.simulate, arm, 1.0, n_saves=3)
    with pytest.raises(TypeError, match="tol"):
        sj.prepare(sj.solve_statics, arm, tol=1e-6)
    f = sjit.jit(lambda x: 3.0 * x)
    seen = []
    jax.jit(lambda x: seen.append(sj.prepare(f, x)) or x)(jnp.ones(2))
    assert seen == [None] and not f.programs and not f.prepared and not tiered


def test_prepared_simulate_and_statics_compile_nothing_at_their_calls(
    tiered, arm, jax_events
):
    """``prepare(simulate, ...)`` with the arguments of a later call (other values,
    the same shapes and settings) compiles its integration and its efforts'
    programs beforehand; ``prepare(solve_statics, ...)`` likewise. The calls then
    compile nothing, and the trajectory equals the one from the program compiled
    at a call (the same program: 1e-15)."""
    from sorojax.statics._solve import _solve_statics

    q = jnp.zeros(arm.n_dof)
    settings = dict(u=_angle, n_save=4, solver="ros34pw2", rtol=2e-4)
    ahead = sj.prepare(sj.simulate, arm, 0.05, q, **settings)
    assert ahead is not None  # the integration's program (default level)
    sj.prepare(sj.solve_statics, arm, q, u=jnp.array([0.3]))
    ahead.result()
    for fn in (simulate_module._saved_extras, _solve_statics):  # compiles ahead
        for program in list(fn.programs.values()):
            if isinstance(program, concurrent.futures.Future):
                program.result()
    # the programs XLA compiles from here on (JAX's events)
    with jax_events("compile") as compiled:
        sol = sj.solve_statics(arm, q, u=jnp.array([0.5]))
        traj = sj.simulate(arm, 0.3, sol.q, **settings)
    # (single operations outside the programs may compile on first use)
    ours = ("_simulate", "_saved_extras", "_solve_statics")
    programs = [name for name in compiled if any(p in name for p in ours)]
    assert not programs, f"compiled again at the prepared calls: {programs}"
    assert traj.efforts.shape == (4, 1)
    simulate_module._simulate.prepared.clear()  # now compiled at the call
    again = sj.simulate(arm, 0.3, sol.q, **settings)
    for a, b in zip(
        (traj.q, traj.qd, traj.efforts),
        (again.q, again.qd, again.efforts),
        strict=True,
    ):
        np.testing.assert_allclose(a, b, rtol=1e-15, atol=1e-15)


def test_tiered_mode_respects_disable_jit(tiered):
    """Under ``jax.disable_jit()`` (debugging) a tiered function runs its Python op
    by op, as a filter_jit does: no program is lowered or compiled for it."""
    seen = []
    f = sjit.jit(lambda x: seen.append(type(x)) or 2.0 * x)
    with jax.disable_jit():
        assert float(f(jnp.asarray(1.5))) == 3.0
    assert not f.programs and not tiered
    assert seen and not issubclass(seen[0], jax.core.Tracer)  # ran on the array


def test_tiered_programs_calls_below_the_budget_stay_at_O0(tiered):
    """Ski rental: calls whose run time adds up to less than the -O0 compile keep the
    -O0 program (no second compile); the time they ran is what is counted."""
    f = sjit.jit(lambda x: x @ x.T)
    x = jnp.ones((4, 4))
    f(x)
    (program,) = f.programs.values()
    program.budget = 1e9  # a compile "longer" than any number of these calls
    for _ in range(20):
        f(x)
    assert len(tiered) == 1 and program.full is None
    assert 0.0 < program.spent < 60.0


def test_tiered_call_on_an_input_still_computing_does_not_wait(tiered):
    """JAX dispatches a compiled program asynchronously: a tiered program whose
    input is still being computed (a slow program's output) returns without waiting
    for it, and that wait is not counted as its run time (before, it was: a cheap
    program after a long integration was promoted at its first call). Its result
    is the same."""
    slow = jax.jit(
        lambda x: jax.lax.fori_loop(0, 10000, lambda i, y: jnp.sin(y @ y.T) / 4, x)
    )
    x = jnp.eye(40) * 0.1
    jax.block_until_ready(slow(x))  # compiled; measure one run
    start = time.perf_counter()
    expect = jax.block_until_ready(slow(x))
    run = time.perf_counter() - start
    f = sjit.jit(lambda y: jnp.sum(y, axis=0))
    f(expect)  # compiled at -O0, its input ready: timed
    (program,) = f.programs.values()
    spent = program.spent
    pending = slow(x)
    assert not pending.is_ready(), "the slow program finished before the call"
    out = f(pending)
    assert program.spent == spent  # the call was not timed
    np.testing.assert_array_equal(np.asarray(out), np.asarray(jnp.sum(expect, 0)))
    assert run > 0.05, f"the slow program took only {run:.3f} s"


def test_tiered_mode_applies_to_top_level_calls_of_sorojax_functions(
    tiered, arm, arm_motion
):
    """``solve_statics`` at top level is a tiered program, with the values of the
    same solve inside a jitted program (1e-12); inside a user's trace it is traced
    into the user's program (no tier, no program of its own)."""
    from sorojax.statics._solve import _solve_statics

    sol = sj.solve_statics(arm, u=jnp.array([0.5]))
    n_programs = len(_solve_statics.programs)
    assert n_programs >= 1, "solve_statics made no tiered program"
    _, (q_static, efforts, *_) = arm_motion  # the same statics inside a jit
    np.testing.assert_allclose(sol.q, q_static, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(sol.efforts, efforts, rtol=1e-12, atol=1e-14)
    jax.eval_shape(lambda th: sj.solve_statics(arm, u=jnp.stack([th])).q, 0.5)
    assert len(_solve_statics.programs) == n_programs


def test_top_level_simulate_computes_the_contact_report_in_a_program_of_its_own(
    tiered,
):
    """In the compile tiers, at top level, the contact report at the save points
    comes from the extras' program (``_saved_extras``, at -O0: the integration's
    program compiles without the contacts' second copy), and so does its result
    code; inside a user's ``jit`` it is part of the one program. Either way it is
    ``contact_state`` at the trajectory's saved states (1e-12 relative: the same
    arithmetic, separately compiled), and a broad phase that overflows is the
    trajectory's result code."""
    from test_contact_kernels import _crossing, _rod

    lk = _rod(12)  # a rod on a floor, 12 samples, settling from rest
    q0 = jnp.zeros(lk.n_dof)
    settings = dict(n_save=3, solver="ros34pw2", throw=False)
    before = dict(simulate_module._saved_extras.programs)
    top = sj.simulate(lk, 0.05, q0, **settings)
    new = [
        k for k in simulate_module._saved_extras.programs if k not in before
    ]  # fmt: skip
    assert len(new) == 1, f"{len(new)} programs for the report (compiled ahead: 1)"
    assert top.efforts is None  # nothing prescribed: the report only
    inside = jax.jit(
        lambda q0: sj.simulate(lk, 0.05, q0, **settings),
        compiler_options=sj.compiler_options(),
    )(q0)
    assert top.result == inside.result == sj.RESULTS.successful
    assert top.contact.force.shape == (3, 12, 3)
    assert float(jnp.max(jnp.abs(top.contact.force))) > 0.0  # in contact
    state = jax.vmap(lambda q, qd, t: sj.contact_state(lk, q, qd, t))
    for tr in (top, inside):
        for a, b in zip(
            jax.tree.leaves(tr.contact),
            jax.tree.leaves(state(tr.q, tr.qd, tr.t)),
            strict=True,
        ):
            np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-13)
    over = _crossing(2)  # fewer candidate pairs than the overlapping ones
    tr = sj.simulate(over, 0.01, jnp.zeros(over.n_dof), n_save=2, max_steps=8,
                     throw=False)  # fmt: skip
    assert tr.result == sj.RESULTS.contact_overflow


def test_top_level_simulate_computes_efforts_in_a_program_of_their_own(
    tiered, arm, arm_motion
):
    """In the compile tiers, at top level, the inputs, prescribed efforts and
    multipliers at the save points come from a program of their own
    (``_saved_extras``, at -O0: the integration's program compiles without that
    copy of the right-hand side); inside a user's ``jit`` they are part of the one
    program. Both give the same values (1e-12 relative: same arithmetic, separately
    compiled)."""
    _, (q_static, _, *inside) = arm_motion  # from inside one jitted program
    before = dict(simulate_module._saved_extras.programs)
    top = sj.simulate(arm, 0.2, q_static, u=_angle, n_save=3, solver="ros34pw2")
    # the efforts' own program: compiled ahead (in a thread, while the integration
    # compiled and ran) for the trajectory's shapes, and used: one new program
    new = {
        k: p
        for k, p in simulate_module._saved_extras.programs.items()
        if k not in before
    }
    assert len(new) == 1, f"{len(new)} programs for the efforts (compiled ahead: 1)"
    (program,) = new.values()
    # (its call's run time counts toward its budget only where the trajectory was
    # ready at the call: here the integration may still be running)
    assert isinstance(program, sjit._TieredProgram)
    # the integration starts at the default level (tiered=False: its one call may
    # run long), so it has no tiered programs; it was traced and lowered first
    # (lower_first), before the efforts' trace started in the thread
    assert not simulate_module._simulate.programs
    compiled = sjit.eqx._compile_utils.Compiled
    assert any(
        isinstance(p, compiled) for p in simulate_module._simulate.prepared.values()
    )
    assert top.efforts.shape == (3, 1) and top.u.shape == (3, 1)
    for a, b in zip((top.q, top.qd, top.u, top.efforts), inside, strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-13)
    np.testing.assert_allclose(top.u[:, 0], _angle(top.t)[0], rtol=1e-14)


def test_a_new_function_object_with_the_same_code_warns_once():
    """A lambda made anew per call is a new static argument (a new program) each
    time: the second object with the same code warns (RecompilationWarning), the same
    object again does not, nor does an equinox.Partial (compared by contents), and
    each code object warns once."""
    import equinox as eqx

    from sorojax._recompile import RecompilationWarning, note_function

    def make(k):
        return lambda t: k * t

    first = make(1.0)
    note_function(first, "u", "test")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        note_function(first, "u", "test")  # the same object: no warning
        note_function(eqx.Partial(_angle), "u", "test")  # contents, not identity
    with pytest.warns(RecompilationWarning, match="u is a new function object"):
        note_function(make(2.0), "u", "test")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        note_function(make(3.0), "u", "test")  # warned once for this code


def test_simulate_notes_its_function_arguments(arm):
    """simulate checks ``u`` before any program is built (here n_save = 0 stops it
    right after): a second lambda of the same code warns."""

    def run():
        sj.simulate(arm, 0.1, u=lambda t: jnp.stack([t]), n_save=0)

    with pytest.raises(ValueError, match="n_save"):
        run()
    with pytest.warns(sj.RecompilationWarning, match="simulate: u is a new"):
        with pytest.raises(ValueError, match="n_save"):
            run()


def test_solve_statics_notes_the_linkage_hooks():
    """A linkage rebuilt with a new hook object of the same code (a new program for
    every call) warns in solve_statics, before anything compiles (a bad q0 stops it
    right after)."""
    rod = sj.SoftLink(
        [
            sj.Division(
                0.3, sj.CircularSection(0.01), sj.LegendreBasis((0, 1, 0, 0, 0, 0), 0)
            )
        ],
        sj.Material(1e6),
    )

    def build():
        return sj.Linkage([rod], custom_wrench=lambda t, q, qd, kin: jnp.zeros((1, 6)))

    def solve():
        lk = build()
        with pytest.raises(ValueError, match="q0"):
            sj.solve_statics(lk, jnp.zeros(lk.n_dof + 1))

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        solve()  # the first hook of this code: no warning
    with pytest.warns(sj.RecompilationWarning, match="Linkage.custom_wrench"):
        solve()
