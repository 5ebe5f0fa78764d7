"""XLA's multi-threaded Eigen calls on and off, side by side (warm speed and compile).

sorojax's models are small: a right-hand side or a Newton iteration is a few hundred
tiny operations (6 x 6 blocks, n_dof of 3 to 60), and XLA's CPU runtime hands each
matrix product to Eigen on its intra-op thread pool by default
(``xla_cpu_multi_thread_eigen``). For products this small the hand-off costs more
than the product. Each program below is compiled twice in one process, with
sorojax's CPU options and ``xla_cpu_multi_thread_eigen`` False ("single") or True
("multi", XLA's default), and the warm runs are interleaved (single, multi, single,
...) so that the machine's drift hits both alike. The programs:

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

    .venv/bin/python benchmarks/eigen_threads.py [--repeats 5] [--order single multi]

Prints a table and writes ``benchmarks/results/eigen_threads_<first>_first.json``.
"""

import argparse
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

from _common import environment  # noqa: E402

RESULTS_DIR = pathlib.Path(__file__).parent / "results"
FLAG = "xla_cpu_multi_thread_eigen"


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

    def cable_loop(Ts):
        return [cable(T) for T in Ts]

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
        "cable statics x40 (loop)": (cable, (t40[0],), lambda c: cable_loop_c(c, t40)),
        "cable statics vmap 256": (jax.vmap(cable), (t256,), None),
        "statics30": (solve_one, (jnp.asarray(5.0),), None),
        "grad free fall 1 s": (jax.grad(tip_z), (jnp.asarray(1.0),), None),
        "PD arm 8 s": (pd, (jnp.asarray(8.0),), None),
        "hybrid statics": (h_statics, (jnp.array([-jnp.pi / 4, 50.0]),), None),
        "hybrid dynamics 1 s": (h_dynamics, (rest,), None),
    }


def cable_loop_c(compiled, Ts):
    """The compiled single-case program called once per tension set."""
    return [compiled(T) for T in Ts]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5, help="timed runs of each")
    ap.add_argument(
        "--order", nargs=2, default=["single", "multi"], choices=["single", "multi"]
    )
    args = ap.parse_args(argv)
    if FLAG not in sj.compiler_options():
        raise SystemExit(f"this XLA does not know {FLAG}: nothing to compare")
    base = {k: v for k, v in sj.compiler_options().items() if k != FLAG}
    variants = {"single": {**base, FLAG: False}, "multi": {**base, FLAG: True}}
    out = {
        "environment": environment(),
        "order": args.order,
        "options": variants,
        "programs": {},
    }
    print(f"jax {jax.__version__}; compiled first: {args.order[0]}")
    for name, (fn, fn_args, run) in programs().items():
        compiled, compile_s = {}, {}
        for mode in args.order:
            t0 = time.perf_counter()
            compiled[mode] = (
                jax.jit(fn, compiler_options=variants[mode]).lower(*fn_args).compile()
            )
            compile_s[mode] = time.perf_counter() - t0

        def call(c, run=run, fn_args=fn_args):
            return run(c) if run is not None else c(*fn_args)

        for c in compiled.values():  # warm-up
            jax.block_until_ready(call(c))
        times = {m: [] for m in compiled}
        for _ in range(args.repeats):
            for mode, c in compiled.items():
                t0 = time.perf_counter()
                jax.block_until_ready(call(c))
                times[mode].append(time.perf_counter() - t0)
        med = {m: statistics.median(v) for m, v in times.items()}
        out["programs"][name] = {
            "compile_s": compile_s,
            "warm_median_s": med,
            "warm_s": times,
        }
        print(
            f"{name:26s} compile single {compile_s['single']:5.2f} s, multi "
            f"{compile_s['multi']:5.2f} s; warm single {1e3 * med['single']:8.1f} ms,"
            f" multi {1e3 * med['multi']:8.1f} ms (multi/single "
            f"{med['multi'] / med['single']:.2f})",
            flush=True,
        )
    RESULTS_DIR.mkdir(parents=True, exist_ok=True)
    path = RESULTS_DIR / f"eigen_threads_{args.order[0]}_first.json"
    path.write_text(json.dumps(out, indent=2))
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
