"""XLA's CPU runtime options on and off, side by side (warm speed and compile).

sorojax's models are small: a right-hand side or a Newton iteration is a few hundred
tiny operations (6 x 6 blocks, n_dof of 3 to 60). Two of XLA's CPU defaults are
made for large arrays:

* ``--option eigen``: ``xla_cpu_multi_thread_eigen`` (XLA's default True): each
  matrix product handed to Eigen on the intra-op thread pool; "on" sets False, as
  ``sorojax.compiler_options()`` does;
* ``--option ynn``: ``xla_cpu_experimental_ynn_fusion_type`` (XLA's default: some
  products and their neighbours as YNNPACK library fusions); "on" sets ``""`` (no
  such fusions: the products stay XLA's own). sorojax does not set it (faster warm
  runs, longer compiles: ``benchmarks/README.md``, tenth round).
* ``--option scheduler``: ``--xla_cpu_enable_concurrency_optimized_scheduler``
  (XLA's default true: a program's independent operations scheduled to run
  concurrently on the thread pool); "on" sets false, as
  ``sorojax.set_runtime_flags()`` does. XLA reads it only from ``XLA_FLAGS`` when
  its backend starts, so each variant runs in processes of its own (``--rounds``
  pairs, alternating which goes first), each compiling every program once and
  timing ``--repeats`` warm runs; the medians over the processes are reported.

Each program below is traced and lowered once and compiled by XLA ``--compiles``
times with the option set ("on") and at XLA's default ("off"), the other options as
``sorojax.compiler_options()``, in alternating order (medians reported); the warm
runs are interleaved (on, off, on, ...) so that the machine's drift hits both
alike. The programs:

* ``rod3 dynamics``: 3 s of the 3-DoF rod with a tip mass of
  ``examples/system_identification.py`` (ROS34PW2, 300 constant steps), and its
  forward-mode Jacobian w.r.t. the 3 parameters (three jvps under vmap);
* ``cable statics x40``: the four-cable arm's statics (8 DoF), 40 tension sets in a
  Python loop; ``... vmap 256``: 256 sets in one vmapped program (batched throughput);
* ``statics30``: the 30-DoF rod of ``benchmarks/statics.py`` (largest matrices here);
* ``grad free fall 1 s``: ``jax.grad`` of the tip height after 1 s of the damped
  free-fall rod (12 DoF, default solver), as in ``benchmarks/latency.py``;
* ``PD arm 8 s``: the PD-controlled arm of ``examples/cable_manipulator.py`` (12 DoF,
  Tsit5, ~4700 steps);
* ``hybrid statics`` / ``hybrid dynamics 1 s``: the manual's 17-DoF closed chain.

Run::

    .venv/bin/python benchmarks/runtime_options.py --option eigen|ynn|scheduler \
        [--repeats 5] [--compiles 3] [--rounds 2] [--order on off]

Prints a table and writes
``benchmarks/results/runtime_options_<option>.json``, overwritten by a re-run (the
order the variants ran in is recorded in it).
"""

import argparse
import functools
import json
import pathlib
import statistics
import sys
import time

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

import sorojax as sj  # noqa: E402

sys.path.insert(0, str(pathlib.Path(__file__).parent))
sys.path.insert(0, str(pathlib.Path(__file__).parent.parent / "examples"))

from _common import environment, interleaved_times  # noqa: E402

RESULTS_DIR = pathlib.Path(__file__).parent / "results"
OPTIONS = {
    "eigen": ("xla_cpu_multi_thread_eigen", False),
    "ynn": ("xla_cpu_experimental_ynn_fusion_type", ""),
}
"""``--option``: the XLA option and its "on" value."""
FLAGS = {
    "scheduler": "--xla_cpu_enable_concurrency_optimized_scheduler=false",
}
"""``--option``: XLA flags read from ``XLA_FLAGS`` only (a process per variant)."""


def programs():
    """``{name: (function, args)}`` (each called as ``compiled(*args)``)."""
    import cable_manipulator as cm
    import system_identification as sid

    from sorojax._mechanisms import cable_manipulator
    from sorojax.scenes import manual_hybrid

    log_p = jnp.log(jnp.asarray(sid.TRUE))
    ts, dt = jnp.linspace(0.0, 3.0, 61), jnp.asarray(0.01)

    arm = cable_manipulator(order=1)
    tip_point = arm.tip_point(1)

    def cable(T):
        sol = sj.solve_statics(arm, u=T, throw=False)
        return sj.forward_kinematics(arm, sol.q)[tip_point, :3, 3]

    rng = np.random.default_rng(0)
    t40 = jnp.asarray(rng.uniform(0.0, 10.0, (40, 4)))
    t256 = jnp.asarray(rng.uniform(0.0, 10.0, (256, 4)))

    from statics import solve_one  # benchmarks/statics.py: the 30-DoF rod

    rod = sj.scenes.free_fall_rod(order=3, eta=1e4)
    q0 = sj.scenes.free_fall_q0(rod)

    def tip_z(s):
        tr = sj.simulate(rod, 1.0, s * q0, n_save=2, throw=False)
        return sj.tip_pose(rod, tr.q[-1])[2, 3]

    ctl_arm = cable_manipulator(order=2, eta=cm.ETA)
    T_ff = jnp.array([8.376, 5.9173, 1.0, 1.0])
    hook = cm.pd_hook(ctl_arm.tip_point(1), (0.1, 0.15, -0.8345), T_ff)
    controlled = cable_manipulator(order=2, eta=cm.ETA, actuator_strength=hook)

    def pd(t1):
        tr = sj.simulate(controlled, t1, n_save=161, rtol=1e-6, atol=1e-8, throw=False)
        return tr.q

    hybrid = manual_hybrid()
    q_ref = jnp.zeros(hybrid.n_dof)
    rest = sj.solve_statics(hybrid, q_ref, u=jnp.zeros(2)).q

    def inputs(t):
        ramp = 0.5 * (1.0 - jnp.cos(jnp.pi * jnp.minimum(t, 1.0)))
        return jnp.stack([jnp.pi * t / 2, 50.0 * ramp])

    def h_statics(u):
        return sj.solve_statics(hybrid, q_ref, u=u, throw=False).q

    def h_dynamics(q0):
        tr = sj.simulate(
            hybrid, 1.0, q0, u=inputs, n_save=11, rtol=1e-6, atol=1e-8, throw=False
        )
        return tr.q

    return {
        "rod3 dynamics": (sid.tip_xz, (log_p, ts, dt), None),
        "rod3 dynamics + Jacobian": (sid._tip_and_jacobian, (log_p, ts, dt), None),
        "cable statics x40 (loop)": (cable, (t40[0],), lambda c: [c(T) for T in t40]),
        "cable statics vmap 256": (jax.vmap(cable), (t256,), None),
        "statics30": (solve_one, (jnp.asarray(5.0),), None),
        "grad free fall 1 s": (jax.grad(tip_z), (jnp.asarray(1.0),), None),
        "PD arm 8 s": (pd, (jnp.asarray(8.0),), None),
        "hybrid statics": (h_statics, (jnp.array([-jnp.pi / 4, 50.0]),), None),
        "hybrid dynamics 1 s": (h_dynamics, (rest,), None),
    }


def _report(name, comp, med):
    """One program's row: compile and warm medians, on against off."""
    print(
        f"{name:26s} compile on {comp['on']:5.2f} s, off {comp['off']:5.2f} s; "
        f"warm on {1e3 * med['on']:8.1f} ms, "
        f"off {1e3 * med['off']:8.1f} ms (off/on {med['off'] / med['on']:.2f})",
        flush=True,
    )


def _write(args, out):
    RESULTS_DIR.mkdir(parents=True, exist_ok=True)
    path = RESULTS_DIR / f"runtime_options_{args.option}.json"
    path.write_text(json.dumps(out, indent=2))
    print(f"wrote {path}")


def _child(repeats):
    """One process's variant: each program compiled once, then warm runs (JSON)."""
    out = {}
    for name, (fn, fn_args, run) in programs().items():
        jitted = jax.jit(fn, compiler_options=sj.compiler_options())
        t0 = time.perf_counter()
        compiled = jitted.lower(*fn_args).compile()
        compile_s = time.perf_counter() - t0
        call = (
            functools.partial(run, compiled)
            if run is not None
            else functools.partial(compiled, *fn_args)
        )
        times = interleaved_times({"x": call}, repeats)["x"]
        out[name] = {"compile_s": compile_s, "warm_median_s": statistics.median(times)}
    print(json.dumps(out))


def _flag_variants(args):
    """``--option`` an XLA flag: the variants in processes of their own."""
    import os
    import subprocess

    flag = FLAGS[args.option]
    name = flag.split("=")[0]
    base = " ".join(
        f for f in os.environ.get("XLA_FLAGS", "").split() if f.split("=")[0] != name
    )
    runs = {"on": [], "off": []}
    for r in range(args.rounds):
        for mode in args.order if r % 2 == 0 else args.order[::-1]:
            env = dict(os.environ, XLA_FLAGS=f"{base} {flag}" if mode == "on" else base)
            env["SOROJAX_CACHE_DIR"] = "off"
            done = subprocess.run(
                [sys.executable, __file__, "--child", "--repeats", str(args.repeats)],
                env=env,
                capture_output=True,
                text=True,
                check=True,
            )
            runs[mode].append(json.loads(done.stdout.strip().splitlines()[-1]))
            print(f"round {r + 1}: {mode} done", flush=True)
    out = {
        "environment": environment(),
        "option": flag,
        "order": args.order,
        "rounds": args.rounds,
        "programs": {},
    }
    for prog in runs["on"][0]:
        comp = {
            m: statistics.median(x[prog]["compile_s"] for x in runs[m]) for m in runs
        }
        med = {
            m: statistics.median(x[prog]["warm_median_s"] for x in runs[m])
            for m in runs
        }
        out["programs"][prog] = {
            "compile_median_s": comp,
            "warm_median_s": med,
            "per_process": {m: [x[prog] for x in runs[m]] for m in runs},
        }
        _report(prog, comp, med)
    _write(args, out)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--option", choices=sorted({*OPTIONS, *FLAGS}), default="eigen")
    ap.add_argument("--repeats", type=int, default=5, help="timed runs of each")
    ap.add_argument("--compiles", type=int, default=3, help="compiles of each")
    ap.add_argument("--rounds", type=int, default=2, help="process pairs (flags)")
    ap.add_argument("--order", nargs=2, default=["on", "off"], choices=["on", "off"])
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        return _child(args.repeats)
    if args.option in FLAGS:
        return _flag_variants(args)
    flag, value = OPTIONS[args.option]
    base = {k: v for k, v in sj.compiler_options().items() if k != flag}
    variants = {"on": {**base, flag: value}, "off": base}
    out = {
        "environment": environment(),
        "option": flag,
        "order": args.order,
        "options": variants,
        "programs": {},
    }
    print(f"jax {jax.__version__}; {flag}; compiled first: {args.order[0]}")
    for name, (fn, fn_args, run) in programs().items():
        # One trace and lowering; XLA compiles it --compiles times per variant, the
        # order alternating (a debug option that matches nothing makes each compile
        # a new cache key, so none is served from JAX's in-memory cache).
        lowered = jax.jit(fn).lower(*fn_args)
        compiled, compile_s = {}, {m: [] for m in args.order}
        for i in range(args.compiles):
            for mode in args.order if i % 2 == 0 else args.order[::-1]:
                options = {**variants[mode], "xla_dump_hlo_module_re": f"^$nomatch{i}"}
                t0 = time.perf_counter()
                compiled[mode] = lowered.compile(compiler_options=options)
                compile_s[mode].append(time.perf_counter() - t0)

        times = interleaved_times(
            {
                m: functools.partial(run, c)
                if run is not None
                else functools.partial(c, *fn_args)
                for m, c in compiled.items()
            },
            args.repeats,
        )
        med = {m: statistics.median(v) for m, v in times.items()}
        comp = {m: statistics.median(v) for m, v in compile_s.items()}
        out["programs"][name] = {
            "compile_median_s": comp,
            "compile_s": compile_s,
            "warm_median_s": med,
            "warm_s": times,
        }
        _report(name, comp, med)
    _write(args, out)


if __name__ == "__main__":
    main()
