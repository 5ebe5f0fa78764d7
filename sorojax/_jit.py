"""sorojax's compiled entry points: ``eqx.filter_jit`` with XLA options of its own.

sorojax's programs are many small fusions and matrix products (6 x 6 adjoints, a
few dozen coordinates). On CPU, XLA's classic (LLVM IR) emitters compile them 20-35%
faster than its newer fusion emitters and run them as fast or faster (the hybrid
scene's dynamics ~30% faster), so sorojax compiles its own programs with
``xla_cpu_use_fusion_emitters = False`` (measured on a 2-core CPU with each program
compiled both ways in one process, warm runs interleaved). Same arithmetic: results
agree to rounding (tested).

The options are probed once, on the first compile: a JAX whose XLA does not know
them, a backend other than CPU, or ``SOROJAX_XLA_OPTIONS=off`` compiles with XLA's
defaults. JAX takes compiler options on top-level jits only: a sorojax call inside
your own ``jax.jit``, ``grad`` or ``vmap`` is compiled with the outer program's
options; pass ``compiler_options=sorojax.compiler_options()`` to your top-level
``jax.jit`` to get these.

Compile tiers (``SOROJAX_COMPILE``, :func:`compile_mode`): XLA's LLVM code generation
is most of a first call's time, and at -O0 it takes about half as long; the code then
runs 3-7x slower (`benchmarks/latency.py`). On a 2-core CPU XLA's compiles are
about half of an example's first run and tracing and lowering about a quarter (JAX's
compile events, per program), hence these tiers and :func:`prepare`. So by default a
top-level sorojax program is first compiled at -O0 and compiled again at XLA's
default level only once its calls have run for as long as that first compile took
("ski rental": a program called once or a few times pays half the compile; a hot one
at most one extra -O0 compile and as much time again in slow calls; the second
compile runs in a worker thread while the calls go on at -O0). The two tiers compute
the same HLO program; results agree to rounding (~1e-15 relative), not bit for bit: set
``SOROJAX_COMPILE=full`` for bit-for-bit repeatable runs.
"""

import concurrent.futures
import functools
import inspect
import numbers
import os
import time
from collections.abc import Callable
from typing import Any, NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

CPU_OPTIONS: dict[str, Any] = {
    # The classic CPU emitters: shorter compiles of sorojax's many small fusions.
    "xla_cpu_use_fusion_emitters": False,
    # Matrix products on the calling thread: sorojax's are tiny (6 x 6 blocks, n_dof
    # up to ~60), and handing each to Eigen's thread pool cost more than the product
    # (warm 1.0-2.0x faster on a 2-core CPU, compiles within noise). XLA's YNNPACK
    # fusions stay on here (LONG_RUN_OPTIONS turns them off).
    "xla_cpu_multi_thread_eigen": False,
}

LONG_RUN_OPTIONS: dict[str, Any] = {
    # XLA's YNNPACK fusions off: sorojax's reductions and products are 6 x 6 blocks
    # and a few dozen coordinates, for which XLA's own loops run faster (2-core CPU:
    # the cable arm's reverse-mode training step of examples/learn_reach.py 0.89-0.90
    # s against 0.96-0.98 s, the clamped 12-DoF rod's forward dynamics 25 against 30
    # us), but compiles take 0-5 % longer (up to 30 % measured on other programs);
    # so for programs that run many times, not by default.
    "xla_cpu_experimental_ynn_fusion_type": "",
}


def compiler_options(long_run: bool = False) -> dict[str, Any]:
    """XLA options sorojax compiles its programs with (a fresh dict each call).

    On CPU, those of :data:`CPU_OPTIONS` that this XLA knows
    (``{"xla_cpu_use_fusion_emitters": False, "xla_cpu_multi_thread_eigen": False}``
    with the jaxlib sorojax is tested with); ``{}`` on other backends and with
    ``SOROJAX_XLA_OPTIONS=off``. Use it for your own jit around sorojax calls::

        jax.jit(f, compiler_options=sorojax.compiler_options())

    Args:
        long_run: also :data:`LONG_RUN_OPTIONS` (those this XLA knows), for a
            program that runs many times (a training step, a long sweep): its
            calls run 5-20 % faster on small models, its compile takes up to 30 %
            longer (0-5 % on a simulation's and a training step's programs).
    """
    return dict(_probed_options(long_run))


def _accepted(options: dict[str, Any]) -> bool:
    """Whether this XLA compiles a tiny program with ``options``."""
    try:
        probe = jax.jit(lambda x: jnp.sin(x) + x, compiler_options=options)
        probe.lower(np.zeros(3)).compile()  # host zeros: no program of their own
    except Exception:  # noqa: BLE001 - an XLA without the option: use its defaults
        return False
    return True


@functools.cache
def _probed_options(long_run: bool = False) -> dict[str, Any]:
    if os.environ.get("SOROJAX_XLA_OPTIONS", "").lower() == "off":
        return {}
    if jax.default_backend() != "cpu":
        return {}
    wanted = {**CPU_OPTIONS, **LONG_RUN_OPTIONS} if long_run else CPU_OPTIONS
    if _accepted(wanted):  # one probe where XLA knows them all
        return dict(wanted)
    # an older or newer XLA: each option it knows (an unknown one fails the compile)
    return {k: v for k, v in wanted.items() if _accepted({k: v})}


RUNTIME_FLAGS: tuple[str, ...] = (
    # XLA's CPU scheduler orders a program's operations for concurrency on the
    # runtime's thread pool; sorojax's are tiny (6 x 6 blocks). Without it: large
    # programs compile 3-10 % faster, warm runs equal or up to 1.3x faster (the
    # hybrid's dynamics), up to 1.8x on a loaded machine (2-core CPU, fresh
    # processes alternating). XLA reads it only from XLA_FLAGS.
    "--xla_cpu_enable_concurrency_optimized_scheduler=false",
)
"""XLA flags :func:`set_runtime_flags` adds (the CPU runtime's, for small programs)."""

_RUNTIME_FLAGS_JAXLIB = "0.10."  # the jaxlib line they are verified on


def set_runtime_flags(threads: int | None = None) -> bool:
    """Add :data:`RUNTIME_FLAGS` to ``XLA_FLAGS`` for this process's CPU backend.

    XLA reads these flags from the environment variable ``XLA_FLAGS`` once, when JAX
    starts its backend (the first array or compile), and not from a program's
    compiler options, so sorojax cannot set them per program; call this first
    thing in a script, before any JAX array exists (the examples do; ``sorojax
    demo``, whose one program runs for a millisecond, does not). They change how
    XLA's CPU runtime runs a compiled program (its operations one after another,
    not scheduled for concurrency), not what it
    computes: the results agree to rounding (the order of operations may change
    the last bits; tested). They apply to every JAX program of the
    process, yours included; a program of large operations (a neural network's
    matrix products, a model of many coordinates: a 63-DoF rope's integration ran
    10-20 % slower with them) may run slower without the concurrency.

    Nothing is changed, and False returned, when JAX's backend has started already,
    with ``SOROJAX_XLA_OPTIONS=off``, or on a jaxlib other than the line the flags
    were verified on (an unknown XLA flag stops the process). A flag already in
    ``XLA_FLAGS`` (yours, with any value) is kept.

    Args:
        threads: the size of XLA's CPU runtime thread pool (``NPROC``, which XLA
            reads when JAX starts its CPU client), where ``NPROC`` is not set
            already; None keeps XLA's default, a thread per core. The runtime hands
            a program's independent operations to that pool, and splits large
            elementwise kernels over it. ``threads=1`` suits small programs run one
            at a time, whose operations are a few microseconds each (2-core CPU,
            fresh processes: a forward-mode rollout step of
            ``examples/crawler_gait.py`` 300-320 against 415-430 us, its whole
            first run 34-36 against 37-39 s in a quiet hour, 45-55 against 58-62 s
            in a busier one; the grasp's evaluation 108 against
            117 us, the 116-DoF rope's 380 against 422 us); the default suits large
            batches (a ``vmap`` over 1024 states of the clamped rod 47-51 against
            34-39 us per case) and large arrays. With one thread, programs called
            from several Python threads at once take turns on it (several host
            devices still run in parallel).

    Returns:
        Whether the flags are in ``XLA_FLAGS`` for the backend JAX will start.
    """
    import importlib.metadata

    from jax._src import xla_bridge

    whole = isinstance(threads, numbers.Integral) and not isinstance(threads, bool)
    if threads is not None and (not whole or threads < 1):
        raise ValueError(
            f"set_runtime_flags(threads={threads!r}): give a whole number of threads, "
            "at least 1, or None for XLA's default (a thread per core)."
        )
    if os.environ.get("SOROJAX_XLA_OPTIONS", "").lower() == "off":
        return False
    if xla_bridge.backends_are_initialized():
        return False
    if not importlib.metadata.version("jaxlib").startswith(_RUNTIME_FLAGS_JAXLIB):
        return False
    current = os.environ.get("XLA_FLAGS", "")
    names = {f.split("=")[0] for f in current.split()}
    missing = [f for f in RUNTIME_FLAGS if f.split("=")[0] not in names]
    os.environ["XLA_FLAGS"] = " ".join([current, *missing]).strip()
    if threads is not None:
        _runtime_threads(threads)
    return True


def _runtime_threads(threads: int) -> bool:
    """``NPROC = threads`` for JAX's CPU client, unless set or the backend is running.

    Whether it was set (XLA reads it once, when JAX starts its backend: a process
    that has run JAX already keeps its pool; a user's ``NPROC`` is kept).
    """
    from jax._src import xla_bridge

    if "NPROC" in os.environ or xla_bridge.backends_are_initialized():
        return False
    os.environ["NPROC"] = str(threads)
    return True


try:  # private: a JAX without it gets XLA's defaults everywhere
    from jax._src.core import trace_state_clean as _trace_state_clean
except ImportError:  # pragma: no cover
    _trace_state_clean = None


def _top_level() -> bool:
    """No JAX trace active (JAX accepts compiler options on top-level jits only)."""
    return _trace_state_clean is not None and _trace_state_clean()


def traced_once(fun: Callable) -> Callable:
    """``fun`` as an inlined ``eqx.filter_jit``: traced once, reused in every program.

    Inside a trace its equations go into the calling program as if traced there (no
    call boundary), but JAX keeps the jaxpr of each argument structure and shape:
    later programs re-emit the cached equations (~10x faster than running the
    Python again: with :func:`sorojax.model.precompute` wrapped so, the manual
    hybrid's six programs trace with 18 % fewer Python calls). It pays for functions
    that many programs call with the same arguments and without tangents
    (:func:`sorojax.model.precompute`). Under ``jvp`` or ``vmap`` JAX transforms the
    cached jaxpr, which on a first call costs the primal trace on top: measured by
    traced Python calls, the kinematic passes wrapped this way traced the manual
    hybrid's programs 3 % faster but the continuation's corrector (a forward-mode
    Jacobian of them) 15 % slower, so they are not. For functions of arrays
    and hashable static values only (a NumPy array argument would become a traced
    input).
    """
    return eqx.filter_jit(fun, inline=True)


MODES = ("tiered", "full", "fast")
FAST_OPTIONS: dict[str, Any] = {"xla_backend_optimization_level": 0}


def compile_mode() -> str:
    """How sorojax compiles top-level programs: ``$SOROJAX_COMPILE``, else ``"tiered"``.

    * ``"tiered"``: the first call of a program (one per argument structure and
      shape, as ``jax.jit``) compiles it with LLVM at -O0; once its calls have run
      for as long as that compile took, it is compiled at XLA's default level, which
      later calls use. Programs that run long by design (``simulate``'s
      integration) start at the default level, with
      ``compiler_options(long_run=True)``.
    * ``"full"``: XLA's default level from the first call (warm timings, bit-for-bit
      repeatable results).
    * ``"fast"``: -O0 for good (short scripts, test suites).

    Tiers apply on CPU with sorojax's XLA options in effect (elsewhere every mode
    is ``"full"``) and to top-level calls only: inside your ``jit``/``grad``/``vmap``
    your program's options apply (wrap it in :func:`jit` to tier it too).
    """
    mode = os.environ.get("SOROJAX_COMPILE", "").strip().lower() or "tiered"
    if mode not in MODES:
        raise ValueError(
            f"SOROJAX_COMPILE={mode!r} is not a compile mode; use one of {MODES} "
            "(or unset it: tiered)."
        )
    return mode


def _signature(args, kwargs) -> tuple:
    """The key ``eqx.filter_jit`` compiles one program per.

    The tree structure, each array's shape and dtype, every other leaf by value
    (filter_jit makes those static).
    """
    leaves, treedef = jax.tree_util.tree_flatten((args, kwargs))
    key: list = [treedef]
    for x in leaves:
        if isinstance(x, jax.Array):
            key.append((x.shape, x.dtype, x.weak_type))
        elif isinstance(x, np.ndarray | np.generic):
            key.append((x.shape, x.dtype, False))  # as jax sees it: not weak
        else:
            key.append(x)
    return tuple(key)


class _TieredProgram:
    """One program of a tiered function: -O0 first, XLA's default level once hot.

    The second compile runs in a worker thread (:data:`_PROMOTE_THREAD`): calls
    keep the -O0 program until it is done, so on a machine with a core to spare
    the compile is off the caller's path.
    """

    __slots__ = (
        "options",
        "lowered",
        "fast",
        "full",
        "budget",
        "spent",
        "promoting",
        "promote_s",
    )

    def __init__(
        self, lower: Callable, options: dict[str, Any], lower_s: float | None = None
    ):
        self.options = options  # of the second compile
        start = time.perf_counter()
        self.lowered = lower()  # traced and lowered once for both tiers
        middle = time.perf_counter()
        if lower_s is not None:  # traced and lowered before (prepare)
            start = middle - lower_s
        self.fast = self.lowered.compile({**options, **FAST_OPTIONS})
        # The budget is the -O0 compile's time, or the trace's and lowering's when
        # longer: a compile loaded from JAX's persistent cache takes milliseconds,
        # but the program is as big (its trace and lowering take about as long as
        # its -O0 compile: 0.8 vs 0.9 s for statics of a 30-DoF rod).
        self.budget = max(time.perf_counter() - middle, middle - start)
        self.spent = 0.0
        self.full = None
        self.promoting: concurrent.futures.Future | None = None
        self.promote_s = None  # the second compile's time, once done

    def _promote(self, lowered):
        start = time.perf_counter()
        full = lowered.compile(self.options)
        self.promote_s = time.perf_counter() - start
        return full

    def __call__(self, promote: bool, args, kwargs):
        if self.promoting is not None and self.promoting.done():
            self.full = self.promoting.result()  # a failed compile raises here
            self.promoting = self.lowered = None
        if self.full is not None:
            return self.full(*args, **kwargs)
        if promote and self.promoting is None and self.spent >= self.budget:
            self.promoting = _PROMOTE_THREAD.submit(self._promote, self.lowered)
        # count the compiled code's run time only: equinox's argument handling around
        # it (~0.1 ms) would not get faster at the default level
        fast = self.fast
        dynamic = fast.preprocess(fast.info, args, kwargs)
        if not _ready(dynamic):
            # An input is still being computed (JAX's asynchronous dispatch, e.g. the
            # trajectory of a running integration): not timed, so the caller is not
            # held until it is done, and the wait is not counted as this program's.
            return fast.postprocess(fast.compiled(*dynamic))
        start = time.perf_counter()
        out = jax.block_until_ready(fast.compiled(*dynamic))
        self.spent += time.perf_counter() - start
        return fast.postprocess(out)


class _Lowered(NamedTuple):
    """A program traced and lowered by ``lower_first``, compiled by its call."""

    lowered: Any
    seconds: float  # the trace's and lowering's


def _ready(tree) -> bool:
    """Whether every JAX array in ``tree`` has been computed."""
    return all(x.is_ready() for x in jax.tree.leaves(tree) if isinstance(x, jax.Array))


def jit(fun: Callable, *, tiered: bool = True, long_run: bool = False) -> Callable:
    """``eqx.filter_jit(fun)`` compiled as sorojax compiles its own programs.

    At top level: with :func:`compiler_options` and in the tiers of
    :func:`compile_mode` (``tiered=False``: at XLA's default level in the tiered
    mode, for programs whose first call runs long, e.g. a whole simulation;
    ``long_run``: with ``compiler_options(long_run=True)``, for programs that run
    many times; a simulation's integration takes both). Inside
    another trace (a ``jit``, ``grad``, ``vmap``) it is the plain
    ``eqx.filter_jit(fun)``: JAX takes compiler options on top-level jits only. The
    options are probed on the first top-level call (not at import, which must not
    start a JAX backend). Use it for your own programs around sorojax calls::

        tips = sorojax.jit(lambda loads: jax.vmap(tip_of)(loads))

    ``f.compile_ahead(*args, **kwargs)`` starts tracing and compiling (at -O0) the
    program of ``f(*args, **kwargs)`` in a worker thread, where it would be
    compiled in tiers (else it does nothing); the call waits for it. Arrays of the
    call's shapes and dtypes do (their values are not used; other arguments as in
    the call): compile a program whose inputs are still being computed, e.g. by
    a long integration.

    ``f.prepare(*args, **kwargs)`` (what :func:`sorojax.prepare` does) traces and
    lowers that program here, in the calling thread, and compiles it in a worker
    thread, in whichever tier the call would use (a program that starts at XLA's
    default level, too); the call waits for the compile.

    ``f.lower_first(*args, **kwargs)`` traces and lowers the program here and
    leaves its compile to the call (in the calling thread, as without it): for a
    caller that starts another program's trace in a worker thread
    (``compile_ahead``) once this one's is done, so that the two traces do not
    take turns on Python's lock. Only at top level.
    """
    plain = eqx.filter_jit(fun)
    tuned: list = []
    programs: dict = {}
    prepared: dict = {}

    def full():
        if not tuned:
            opts = _probed_options(long_run)
            tuned.append(eqx.filter_jit(fun, compiler_options=opts) if opts else plain)
        return tuned[0]

    def new_program(args, kwargs):
        return _TieredProgram(
            functools.partial(plain.lower, *args, **kwargs), _probed_options(long_run)
        )

    def tiers_for(mode: str) -> bool:
        """This function's top-level calls compile in tiers in ``mode``."""
        return _in_tiers(mode) and (tiered or mode != "tiered")

    @functools.wraps(fun)
    def call(*args, **kwargs):
        if not _top_level():
            return plain(*args, **kwargs)
        mode = compile_mode()
        if not tiers_for(mode):
            if prepared:  # by prepare or lower_first (else no signature is taken)
                compiled = _prepared_program(
                    prepared, _signature(args, kwargs), _probed_options(long_run)
                )
                if compiled is not None:
                    return compiled(*args, **kwargs)
            return full()(*args, **kwargs)
        key = _signature(args, kwargs)
        program = programs.get(key)
        if isinstance(program, concurrent.futures.Future):  # compiled ahead
            try:
                program = programs[key] = program.result()
            except BaseException:
                programs.pop(key, None)  # a later call traces again
                raise
        if isinstance(program, _Lowered):  # traced and lowered by lower_first
            try:
                program = programs[key] = _TieredProgram(
                    lambda: program.lowered, _probed_options(long_run), program.seconds
                )
            except BaseException:
                programs.pop(key, None)  # a later call traces again
                raise
        if program is None:
            program = programs[key] = new_program(args, kwargs)
        return program(mode == "tiered", args, kwargs)

    def lower_first(*args, **kwargs) -> None:
        """Trace and lower ``call(*args, **kwargs)``'s program now.

        The call compiles it (see the ``jit`` docstring). Only at top level.
        """
        if not _top_level():
            return
        key = _signature(args, kwargs)
        start = time.perf_counter()
        if tiers_for(compile_mode()):
            if key not in programs:
                lowered = plain.lower(*args, **kwargs)
                programs[key] = _Lowered(lowered, time.perf_counter() - start)
        elif key not in prepared:
            lowered = full().lower(*args, **kwargs)
            prepared[key] = _Lowered(lowered, time.perf_counter() - start)

    def compile_ahead(*args, **kwargs) -> concurrent.futures.Future | None:
        """Start compiling the program of ``call(*args, **kwargs)`` in a thread.

        For a call whose arguments' shapes are known before their values (the
        efforts and contact report at a trajectory's save points, while the
        integration runs): the trace, the lowering and the -O0 compile run beside
        the caller's work, and the call waits for them. Only where the call would
        compile in tiers (elsewhere nothing is done: None). Returns the future of
        the program.
        """
        if not (_top_level() and tiers_for(compile_mode())):
            return None
        key = _signature(args, kwargs)
        if key in programs:
            return None
        _probed_options(long_run)  # probed here, not in the thread
        future = programs[key] = _COMPILE_THREAD.submit(new_program, args, kwargs)
        return future

    def prepare(*args, **kwargs) -> concurrent.futures.Future | None:
        """Trace and lower ``call(*args, **kwargs)``'s program; compile it in a thread.

        For a program needed later in a script (a simulation after the statics):
        its XLA compile, which does not hold Python's lock, runs while the caller
        goes on, and the call waits for it. The trace stays in the calling thread
        (traces in two threads would only take turns). Only at top level; nothing
        is done (None) for a program already compiled or prepared here.
        """
        if not _top_level():
            return None
        mode = compile_mode()
        key = _signature(args, kwargs)
        if tiers_for(mode):
            if key in programs:
                return None
            start = time.perf_counter()
            lowered = plain.lower(*args, **kwargs)
            future = programs[key] = _COMPILE_THREAD.submit(
                _TieredProgram,
                lambda: lowered,
                _probed_options(long_run),
                time.perf_counter() - start,
            )
            return future
        if key in prepared:
            return None
        lowered = full().lower(*args, **kwargs)
        future = prepared[key] = _COMPILE_THREAD.submit(
            lowered.compile, _probed_options(long_run) or None
        )
        return future

    call.programs = programs  # the tiered programs, by signature (for inspection)
    call.prepared = prepared  # at the default level: by prepare, or lower_first
    call.compile_ahead = compile_ahead
    call.lower_first = lower_first
    call.prepare = prepare
    # ahead-of-time compilation, as on a filter_jit: f.lower(*args).compile()
    call.lower = lambda *a, **kw: (full() if _top_level() else plain).lower(*a, **kw)
    return call


def prepare(fn: Callable, /, *args, **kwargs) -> concurrent.futures.Future | None:
    """Compile ``fn(*args, **kwargs)``'s programs in a worker thread, for a later call.

    A script's first run waits for XLA to compile each program as it comes to it
    (statics, then a simulation, ...). ``prepare`` traces and lowers the programs of
    a later call now, in the calling thread, and compiles them in a worker thread
    while the script goes on; XLA's compile does not hold Python's lock, so on a
    machine with a core to spare it runs beside the script's other work. Two compiles
    at once share the cores (together 1.1-1.3x faster than one after the other on a
    2-core CPU), so the gain is mostly the calling thread's own work meanwhile: the
    manual hybrid's statics followed by 1 s of dynamics take 11.7 s from the first
    call to the trajectory with the dynamics prepared first, against 12.8 s without
    (medians of four fresh processes each, cache off, 2-core CPU). The later call
    with arguments of the same shapes and the same settings waits for the compile
    instead of compiling. Nothing is computed: array values do not matter,
    except where ``fn`` decides on the host from them (``simulate``'s
    ``solver="auto"`` picks the solver from ``q0``, ``t0`` and ``t1``: name it).

    Args:
        fn: :func:`sorojax.simulate`, :func:`sorojax.solve_statics`,
            :func:`sorojax.continuation`, or a :func:`sorojax.jit` function.
        *args: the later call's arguments (arrays of its shapes and dtypes).
        **kwargs: its keyword arguments.

    Returns:
        The future of the (main) compile, or None where nothing is to be done: inside
        a trace, or for a program already compiled or prepared.

    Raises:
        TypeError: ``fn`` is not one of these.

    Example::

        ahead = sj.prepare(sj.simulate, linkage, 2.0, q_ref, u=u_of_t, solver="tsit5")
        sol = sj.solve_statics(linkage, q_ref, u=u0)  # compiles meanwhile
        traj = sj.simulate(linkage, 2.0, sol.q, u=u_of_t, solver="tsit5")
    """
    hook = getattr(fn, "prepare", None)
    if hook is None:
        raise TypeError(
            "sorojax.prepare takes sorojax.simulate, sorojax.solve_statics, "
            "sorojax.continuation or a function made by sorojax.jit; got "
            f"{fn!r}. Wrap your own function with sorojax.jit to prepare it."
        )
    return hook(*args, **kwargs)


def _bound_arguments(fn: Callable, args, kwargs, host_only=()) -> dict:
    """``fn``'s parameters bound to a call's ``args`` and ``kwargs``, by name.

    Defaults filled in, ``host_only`` parameters (those that do not change the
    compiled program) left out. For the ``prepare`` of sorojax's entry points: a
    wrong argument raises ``TypeError`` as the call itself would.
    """
    call = inspect.signature(fn).bind(*args, **kwargs)
    call.apply_defaults()
    return {k: v for k, v in call.arguments.items() if k not in host_only}


def _prepared_program(prepared: dict, key, options: dict):
    """The compiled program :func:`jit`'s ``prepare`` made for ``key``, or None.

    Waits for its compile, or compiles one that ``lower_first`` lowered (with
    ``options``); a failed compile is dropped (the call then compiles as usual and
    raises there).
    """
    program = prepared.get(key)
    if isinstance(program, _Lowered):
        try:
            program = prepared[key] = program.lowered.compile(options or None)
        except Exception:
            prepared.pop(key, None)
            return None
    if isinstance(program, concurrent.futures.Future):
        try:
            program = prepared[key] = program.result()
        except Exception:
            prepared.pop(key, None)
            return None
    return program


# One worker thread for programs compiled ahead (started on the first submit), and
# one for the second tier's compiles (so that a program compiled ahead never waits
# behind a long promotion).
_COMPILE_THREAD = concurrent.futures.ThreadPoolExecutor(1, "sorojax-compile-ahead")
_PROMOTE_THREAD = concurrent.futures.ThreadPoolExecutor(1, "sorojax-promote")


def _in_tiers(mode: str) -> bool:
    """Top-level calls compile in tiers now (``mode``: :func:`compile_mode`).

    Not in the ``full`` mode, not under ``jax.disable_jit`` (filter_jit then runs
    the Python as is), and only where -O0 means LLVM's CPU code generation: on CPU
    with sorojax's options.
    """
    return mode != "full" and not jax.config.jax_disable_jit and _tiers_apply()


def in_tiers() -> bool:
    """A top-level call made here would be compiled in tiers (outside any trace)."""
    return _top_level() and _in_tiers(compile_mode())


@functools.cache
def _tiers_apply() -> bool:
    return bool(_probed_options()) and jax.default_backend() == "cpu"
