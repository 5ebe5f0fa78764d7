"""Side-by-side timing of sorojax's XLA options against XLA's defaults.

Each program is jitted twice in one process, once with ``sorojax.compiler_options()``
(the classic CPU emitters) and once without, and the warm timings are interleaved
(on, off, on, off, ...) so that the machine's drift hits both alike. Programs: the
four-cable arm's statics for 40 tension sets in a Python loop, the manual hybrid
scene's statics, and 1 s of its dynamics.

Compile times: the second compile of a pair reuses the traces of sorojax's inner
functions made for the first, so run twice with the order swapped
(``--order on off`` and ``--order off on``) and compare each variant where it came
first.

Run::

    .venv/bin/python benchmarks/xla_options.py [--order on off] [--repeats 7]

Prints a table and writes ``benchmarks/results/xla_options_<order>.json``.
"""

import argparse
import functools
import json
import os
import pathlib
import statistics
import time

# warm timings at XLA's default level from the first call (sorojax.compile_mode)
os.environ.setdefault("SOROJAX_COMPILE", "full")

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
from _common import interleaved_times  # noqa: E402

import sorojax as sj  # noqa: E402
from sorojax._mechanisms import cable_manipulator  # noqa: E402
from sorojax.scenes import manual_hybrid  # noqa: E402

RESULTS_DIR = pathlib.Path(__file__).parent / "results"


def programs():
    """``{name: (function, args, runner)}``; runner(compiled) does the timed work."""
    arm = cable_manipulator(order=2)
    tip_point = arm.tip_point(1)

    def cable(T):
        sol = sj.solve_statics(arm, u=T, throw=False)
        return sj.forward_kinematics(arm, sol.q)[tip_point, :3, 3], sol.num_steps

    tensions = jnp.asarray(np.random.default_rng(0).uniform(0.0, 15.0, (40, 4)))

    hybrid = manual_hybrid()
    q_ref = jnp.zeros(hybrid.n_dof)

    def statics(u):
        return sj.solve_statics(hybrid, q_ref, u=u, throw=False).q

    rest = sj.solve_statics(hybrid, q_ref, u=jnp.zeros(2)).q

    def inputs(t):
        ramp = 0.5 * (1.0 - jnp.cos(jnp.pi * jnp.minimum(t, 1.0)))
        return jnp.stack([jnp.pi * t / 2, 50.0 * ramp])

    def dynamics(q0):
        tr = sj.simulate(
            hybrid, 1.0, q0, u=inputs, n_save=11, rtol=1e-6, atol=1e-8,
            solver="tsit5", throw=False,
        )  # fmt: skip
        return tr.q

    u_st = jnp.array([-jnp.pi / 4, 50.0])
    return {
        "cable statics x40 (loop)": (
            cable,
            (tensions[0],),
            lambda c: [c(T) for T in tensions],
        ),
        "hybrid statics": (statics, (u_st,), lambda c: c(u_st)),
        "hybrid dynamics 1 s": (dynamics, (rest,), lambda c: c(rest)),
    }


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--order", nargs=2, default=["on", "off"], choices=["on", "off"])
    ap.add_argument("--repeats", type=int, default=7, help="timed runs (dynamics: 3)")
    args = ap.parse_args(argv)
    opts = sj.compiler_options()
    if not opts:
        raise SystemExit("sorojax.compiler_options() is empty here: nothing to compare")
    print(f"jax {jax.__version__}, {os.cpu_count()} CPUs, options {opts}")
    out = {"order": args.order, "options": opts, "programs": {}}
    for name, (fn, fn_args, run) in programs().items():
        compiled, compile_s = {}, {}
        for mode in args.order:
            t0 = time.perf_counter()
            jitted = jax.jit(fn, compiler_options=opts if mode == "on" else None)
            compiled[mode] = jitted.lower(*fn_args).compile()
            compile_s[mode] = time.perf_counter() - t0
        times = interleaved_times(
            {m: functools.partial(run, c) for m, c in compiled.items()},
            3 if "dynamics" in name else args.repeats,
        )
        med = {m: statistics.median(v) for m, v in times.items()}
        out["programs"][name] = {"compile_s": compile_s, "warm_median_s": med}
        print(
            f"{name:26s} compile on {compile_s['on']:5.2f} s, off "
            f"{compile_s['off']:5.2f} s (first: {args.order[0]}); warm on "
            f"{1e3 * med['on']:8.1f} ms, off {1e3 * med['off']:8.1f} ms "
            f"(off/on {med['off'] / med['on']:.2f})"
        )
    RESULTS_DIR.mkdir(parents=True, exist_ok=True)
    path = RESULTS_DIR / f"xla_options_{args.order[0]}_first.json"
    path.write_text(json.dumps(out, indent=2))
    print(f"Wrote {path}")


if __name__ == "__main__":
    main()
