"""First-call latency: where a cold first call's time goes, per program.

Each target runs in a fresh Python process with JAX's persistent compilation cache
off, as a new user's first call. It is one top-level ``jax.jit`` (sorojax's compiler
options), staged by hand with JAX's ahead-of-time API: ``trace`` (Python ->
jaxpr: sorojax's model code runs here), ``lower`` (jaxpr -> StableHLO), ``compile``
(XLA), then the first call and the median of warm calls. The size of the optimised
HLO (instructions) is reported with each.

Targets:

* ``statics30``: statics of the 30-DoF rod of ``benchmarks/statics.py`` (torsion and
  two bendings, order 9; tip load P L^2/EI = 5 plus 0.5 out of plane);
* ``freefall5``: 5 s of the damped free-fall rod (``free_fall_rod(order=3,
  eta=1e4)``, 12 DoF, default solver);
* ``cablearm16``: 1 s of the four-cable arm, two divisions of order 3 (16 DoF),
  constant tensions, default solver;
* ``hybrid_statics`` / ``hybrid_dynamics``: the manual's 17-DoF hybrid closed chain
  (statics at -pi/4 and 50 N; 1 s with the angle pi t / 2);
* ``grad_freefall1``: ``jax.grad`` of the tip height after 1 s of the damped
  free-fall rod with respect to the scale of its initial strain;
* ``fwdgrad_freefall1``: the same derivative in forward mode (``jax.jacfwd``
  through ``simulate(..., adjoint=diffrax.ForwardMode())``: one tangent, the mode
  to use for a few parameters).

Run::

    .venv/bin/python benchmarks/latency.py [--targets ...] [--repeats 5] [--tag T]
        [--tiered]

``--tiered`` also times each target through ``sorojax.jit`` in the default compile
tiers (a second fresh process: the first call at -O0, the calls until the program
is compiled again at XLA's default level, then warm calls; ``sorojax.compile_mode``).
Writes ``benchmarks/results/latency.json`` (``latency_<T>.json`` with ``--tag T``),
overwritten by a re-run, and prints a table.
"""

import argparse
import json
import pathlib
import statistics
import subprocess
import sys
import time

TARGETS = (
    "statics30",
    "freefall5",
    "cablearm16",
    "hybrid_statics",
    "hybrid_dynamics",
    "grad_freefall1",
    "fwdgrad_freefall1",
)
RESULTS_DIR = pathlib.Path(__file__).parent / "results"


def build(name):
    """``(function, args, n_dof)`` of a target (imports JAX: child process only)."""
    import jax.numpy as jnp

    import sorojax as sj
    from sorojax import scenes
    from sorojax._mechanisms import cable_manipulator

    if name == "statics30":
        L, R, E = 1.0, 0.01, 1e7
        P = 5.0 * E * 3.141592653589793 * R**4 / 4 / L**2

        def f(alpha):
            w = jnp.array([0.0, 0.0, 0.0, 0.0, 1.0, 0.1]) * P * alpha
            lk = scenes.cantilever(
                L, R, E, modes=(1, 1, 1, 0, 0, 0), order=9, tip_wrench=w
            )
            sol = sj.solve_statics(lk, throw=False)
            return sol.q, sol.result._value

        return f, (jnp.asarray(1.0),), 30
    if name in ("freefall5", "grad_freefall1", "fwdgrad_freefall1"):
        rod = scenes.free_fall_rod(order=3, eta=1e4)
        q0 = scenes.free_fall_q0(rod)
        if name == "freefall5":

            def f(s):
                tr = sj.simulate(rod, 5.0, s * q0, n_save=2, throw=False)
                return tr.q[-1], tr.result._value

            return f, (jnp.asarray(1.0),), rod.n_dof

        import diffrax
        import jax

        forward_mode = name == "fwdgrad_freefall1"
        adjoint = diffrax.ForwardMode() if forward_mode else None

        def tip_z(s):
            tr = sj.simulate(rod, 1.0, s * q0, n_save=2, throw=False, adjoint=adjoint)
            return sj.tip_pose(rod, tr.q[-1])[2, 3]

        derivative = jax.jacfwd(tip_z) if forward_mode else jax.grad(tip_z)
        return derivative, (jnp.asarray(1.0),), rod.n_dof
    if name == "cablearm16":
        arm = cable_manipulator(order=3, eta=3e4)

        def f(T):
            tr = sj.simulate(arm, 1.0, u=T, n_save=2, throw=False)
            return tr.q[-1], tr.result._value

        return f, (jnp.full(4, 2.0),), arm.n_dof
    if name.startswith("hybrid"):
        lk = scenes.manual_hybrid()
        if name == "hybrid_statics":

            def f(u):
                sol = sj.solve_statics(lk, u=u, throw=False)
                return sol.q, sol.result._value

            return f, (jnp.array([-jnp.pi / 4, 50.0]),), lk.n_dof
        # The assembled rest shape (statics at zero inputs) starts the motion.
        rest = sj.solve_statics(lk, u=jnp.zeros(2)).q

        def inputs(t):
            ramp = 0.5 * (1.0 - jnp.cos(jnp.pi * jnp.minimum(t, 1.0)))
            return jnp.stack([jnp.pi * t / 2, 50.0 * ramp])

        def f(s):
            tr = sj.simulate(lk, 1.0, s * rest, u=inputs, n_save=2, throw=False)
            return tr.q[-1], tr.result._value

        return f, (jnp.asarray(1.0),), lk.n_dof
    raise ValueError(f"unknown target {name!r}: give one of {TARGETS}")


def start(name):
    """A child's set-up: JAX (x64, cache off), every sorojax module, the target."""
    import jax

    jax.config.update("jax_enable_x64", True)
    jax.config.update("jax_enable_compilation_cache", False)
    import sorojax as sj

    for public in sj.__all__:  # import every module now (sorojax imports lazily), so
        getattr(sj, public)  # that the timed first call times no imports
    return jax, sj, *build(name)


def child(name, repeats):
    """Measure one target in this (fresh) process; print one JSON line."""
    t_start = time.perf_counter()
    jax, sj, f, args, n_dof = start(name)
    t_import = time.perf_counter() - t_start
    jitted = jax.jit(f, compiler_options=sj.compiler_options())
    t = time.perf_counter()
    traced = jitted.trace(*args)
    t_trace = time.perf_counter() - t
    t = time.perf_counter()
    lowered = traced.lower()
    t_lower = time.perf_counter() - t
    t = time.perf_counter()
    compiled = lowered.compile()
    t_compile = time.perf_counter() - t
    t = time.perf_counter()
    first = jax.block_until_ready(compiled(*args))
    t_first = time.perf_counter() - t
    # result code of the run (0: successful); a gradient has none
    result = int(first[1]) if isinstance(first, tuple) else 0
    warm = []
    for _ in range(repeats):
        t = time.perf_counter()
        jax.block_until_ready(compiled(*args))
        warm.append(time.perf_counter() - t)
    hlo = compiled.as_text() or ""
    print(
        json.dumps(
            {
                "target": name,
                "n_dof": n_dof,
                "import_build_s": t_import,
                "trace_s": t_trace,
                "lower_s": t_lower,
                "compile_s": t_compile,
                "first_run_s": t_first,
                "first_call_total_s": t_trace + t_lower + t_compile + t_first,
                "warm_median_s": statistics.median(warm),
                "hlo_lines": hlo.count("\n"),
                "result": result,
            }
        )
    )


def child_tiered(name, repeats):
    """The same target through ``sorojax.jit`` in the tiered compile mode.

    One wall time for the first call (trace, lower, -O0 compile, run), then calls
    until the program is compiled at XLA's default level (in a worker thread while
    the -O0 calls go on: its compile time as the thread timed it), then the median
    of warm calls. Prints one JSON line.
    """
    import os

    os.environ["SOROJAX_COMPILE"] = "tiered"
    jax, sj, f, args, n_dof = start(name)
    jitted = sj.jit(f)
    t = time.perf_counter()
    jax.block_until_ready(jitted(*args))
    first = time.perf_counter() - t
    (program,) = jitted.programs.values()
    slow, calls = [], 1
    while program.full is None and calls < 10_000:
        t = time.perf_counter()
        jax.block_until_ready(jitted(*args))
        slow.append(time.perf_counter() - t)
        calls += 1
    # the second compile runs in a worker thread while the -O0 calls go on; the
    # call that finds it done switches to it (its time is a warm call's)
    if program.full is not None:
        slow.pop()
    promoting = program.promote_s if program.promote_s is not None else float("nan")
    warm = []
    for _ in range(repeats):
        t = time.perf_counter()
        jax.block_until_ready(jitted(*args))
        warm.append(time.perf_counter() - t)
    print(
        json.dumps(
            {
                "target": name,
                "n_dof": n_dof,
                "mode": "tiered",
                "first_call_total_s": first,
                "fast_compile_s": program.budget,
                "fast_calls_after_first": len(slow),
                "fast_call_median_s": statistics.median(slow) if slow else None,
                "promote_compile_s": promoting,
                "warm_median_s": statistics.median(warm),
            }
        )
    )


def run_child(flag, name, repeats):
    """One target in a fresh process (``flag``: --child or --child-tiered): its row."""
    out = subprocess.run(
        [sys.executable, __file__, flag, name, "--repeats", str(repeats)],
        capture_output=True,
        text=True,
    )
    if out.returncode:
        print(f"{name} ({flag}): failed\n{out.stderr[-2000:]}", flush=True)
        return None
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--targets", nargs="*", default=list(TARGETS))
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--tag", default="")
    ap.add_argument(
        "--tiered",
        action="store_true",
        help="also time each target through sorojax.jit in the tiered compile mode",
    )
    ap.add_argument("--child", default=None, help=argparse.SUPPRESS)
    ap.add_argument("--child-tiered", default=None, help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.child:
        child(a.child, a.repeats)
        return
    if a.child_tiered:
        child_tiered(a.child_tiered, a.repeats)
        return
    sys.path.insert(0, str(pathlib.Path(__file__).parent))
    import jax
    from _common import environment

    jax.config.update("jax_enable_x64", True)
    rows = []
    print(
        f"{'target':16s} {'ndof':>4s} {'trace':>7s} {'lower':>7s} {'compile':>8s} "
        f"{'1st run':>8s} {'total':>7s} {'warm':>9s} {'HLO':>7s}",
        flush=True,
    )
    for name in a.targets:
        r = run_child("--child", name, a.repeats)
        if r is None:
            continue
        rows.append(r)
        print(
            f"{name:16s} {r['n_dof']:4d} {r['trace_s']:6.2f}s {r['lower_s']:6.2f}s "
            f"{r['compile_s']:7.2f}s {r['first_run_s']:7.3f}s "
            f"{r['first_call_total_s']:6.2f}s {1e3 * r['warm_median_s']:7.2f}ms "
            f"{r['hlo_lines']:7d}  result {r['result']}",
            flush=True,
        )
        r = run_child("--child-tiered", name, a.repeats) if a.tiered else None
        if r is None:
            continue
        rows.append(r)
        print(
            f"{'  tiered':16s} first call {r['first_call_total_s']:.2f}s (-O0 compile "
            f"{r['fast_compile_s']:.2f}s), {r['fast_calls_after_first']} more -O0 "
            f"calls (the default level compiling in {r['promote_compile_s']:.2f}s in a "
            f"thread); warm {1e3 * r['warm_median_s']:.2f}ms",
            flush=True,
        )
    RESULTS_DIR.mkdir(exist_ok=True)
    path = RESULTS_DIR / f"latency{('_' + a.tag) if a.tag else ''}.json"
    path.write_text(json.dumps({"environment": environment(), "rows": rows}, indent=1))
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
