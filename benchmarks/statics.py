"""Speed benchmark: kinematics and statics of Cosserat rods (sorojax).

Run from the repository root::

    .venv/bin/python benchmarks/statics.py            # full run (~3-4 min on 2 CPU cores)
    .venv/bin/python benchmarks/statics.py --quick    # fewer repeats, smaller batch check

Measures (compile time reported separately from warm time; warm figures are the
median of repeated calls after a warm-up, each ended with ``jax.block_until_ready``):

1. ``sorojax.forward_kinematics`` and ``sorojax.jacobians`` of a 12-DoF rod (torsion +
   two bendings, cubic Legendre basis).
2. ``sorojax.solve_statics`` of a 30-DoF rod (torsion + two bendings, order 9) under a
   large 3D tip load, P L^2 / (E I) = 5 in-plane plus 10 % out of plane.
3. 1024 such solves (loads spread over P L^2/(E I) in [0.5, 5]) batched with ``vmap``
   (all at once, and in chunks with ``lax.map(batch_size=...)``) versus one at a
   time (a Python loop over a jitted single solve; 32 solves timed, extrapolated).

Prints a table and writes ``benchmarks/results/statics.json``.
"""

import argparse
import json
import math
import os
import time
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
from _common import compile_time, environment, timed  # noqa: E402

import sorojax  # noqa: E402
from sorojax.scenes import cantilever  # noqa: E402

RESULTS_DIR = Path(__file__).resolve().parent / "results"

# Rod used throughout: L = 1 m, r = 1 cm, E = 1e7 Pa.
L, R, E = 1.0, 0.01, 1e7
I = math.pi * R**4 / 4
EI_L2 = E * I / L**2  # P for alpha = P L^2 / (E I) = 1
SOROSIM_30DOF_STATICS_S = 0.5  # SoRoSim (MATLAB) figure for a 30-DoF statics solve
OUT_OF_PLANE = 0.1  # z-force as a fraction of the y-force (makes the problem 3D)

MODES_12 = (1, 1, 1, 0, 0, 0)  # torsion + bending about y and z
ORDER_12 = 3  # cubic: 3 modes x 4 = 12 DoF
MODES_30 = (1, 1, 1, 0, 0, 0)
ORDER_30 = 9  # 3 modes x 10 = 30 DoF


def tip_wrench(alpha):
    """World-frame tip wrench for a dimensionless load alpha (traceable)."""
    P = alpha * EI_L2
    return jnp.array([0.0, 0.0, 0.0, 0.0, 1.0, OUT_OF_PLANE]) * P


def rod30(alpha):
    return cantilever(
        L, R, E, modes=MODES_30, order=ORDER_30, tip_wrench=tip_wrench(alpha)
    )


def solve_one(alpha):
    """One statics solve of the 30-DoF rod; the linkage is built from a traced load."""
    sol = sorojax.solve_statics(rod30(alpha), throw=False)
    return sol.q, sol.residual_norm, sol.num_steps, sol.result._value


def bench_kinematics(repeats):
    rod = cantilever(L, R, E, modes=MODES_12, order=ORDER_12)
    n = rod.n_dof
    q = jnp.asarray(np.random.default_rng(0).normal(scale=0.5, size=n))
    out = {"n_dof": n, "modes": MODES_12, "order": ORDER_12}
    for name, fn in (
        ("forward_kinematics", sorojax.forward_kinematics),
        ("jacobians", sorojax.jacobians),
    ):
        compiled, tc = compile_time(fn, rod, q)
        med, best = timed(compiled, rod, q, repeats=repeats)
        # Also the ordinary call path (filter_jit dispatch, cache lookup) once warm.
        fn(rod, q)
        med_call, _ = timed(fn, rod, q, repeats=repeats)
        shape = tuple(fn(rod, q).shape)
        out[name] = {
            "compile_s": tc,
            "warm_median_s": med,
            "warm_min_s": best,
            "warm_median_via_filter_jit_call_s": med_call,
            "output_shape": shape,
        }
    return out


def bench_single_statics(repeats):
    alpha = 5.0
    jitted = jax.jit(solve_one)
    compiled, tc = compile_time(jitted, alpha)
    q, res, steps, result = jax.block_until_ready(compiled(alpha))
    med, best = timed(compiled, alpha, repeats=repeats)
    # Same solve through the public filter_jit entry point with a concrete linkage.
    rod = rod30(alpha)
    t0 = time.perf_counter()
    sol = jax.block_until_ready(sorojax.solve_statics(rod))
    first_public = time.perf_counter() - t0
    med_public, _ = timed(lambda: sorojax.solve_statics(rod).q, repeats=repeats)
    tip = np.asarray(sorojax.tip_pose(rod, q))[:3, 3]
    return {
        "n_dof": int(q.shape[0]),
        "modes": MODES_30,
        "order": ORDER_30,
        "alpha_y": alpha,
        "alpha_z": alpha * OUT_OF_PLANE,
        "tip_force_N": np.asarray(tip_wrench(alpha))[3:].tolist(),
        "compile_s": tc,
        "warm_median_s": med,
        "warm_min_s": best,
        "public_solve_statics_first_call_s": first_public,
        "public_solve_statics_warm_median_s": med_public,
        "newton_iterations": int(steps),
        "residual_max_norm": float(res),
        "result_code": int(result),
        "public_result_matches": bool(np.allclose(sol.q, q, atol=1e-10)),
        "tip_position_m": tip.tolist(),
        "sorosim_ratio": SOROSIM_30DOF_STATICS_S / med,
    }


def bench_batch(n_batch, n_loop, repeats, batch_repeats, chunk):
    alphas = jnp.linspace(0.5, 5.0, n_batch)
    out = {"n_batch": n_batch, "alpha_range": [0.5, 5.0]}

    # One at a time: a Python loop over the jitted single solve (already compiled).
    single = jax.jit(solve_one)
    jax.block_until_ready(single(alphas[0]))
    idx = np.linspace(0, n_batch - 1, n_loop).astype(int)
    sub = [alphas[i] for i in idx]

    def loop():
        return [single(a)[0] for a in sub]

    med, _ = timed(loop, repeats=repeats)
    per_loop = med / n_loop
    out["loop"] = {
        "n_timed": n_loop,
        "time_for_n_timed_s": med,
        "per_solve_s": per_loop,
        "solves_per_s": 1.0 / per_loop,
        "extrapolated_total_s": per_loop * n_batch,
    }

    variants = [("vmap", jax.jit(jax.vmap(solve_one)))]
    if chunk:
        variants.append(
            (
                f"lax.map(batch_size={chunk})",
                jax.jit(lambda a: jax.lax.map(solve_one, a, batch_size=chunk)),
            )
        )
    for name, fn in variants:
        compiled, tc = compile_time(fn, alphas)
        q, res, steps, result = jax.block_until_ready(compiled(alphas))
        med, best = timed(compiled, alphas, repeats=batch_repeats, warmup=False)
        out[name] = {
            "compile_s": tc,
            "warm_median_s": med,
            "warm_min_s": best,
            "repeats": batch_repeats,
            "per_solve_s": med / n_batch,
            "solves_per_s": n_batch / med,
            "speedup_vs_loop": per_loop * n_batch / med,
            "n_failed": int(np.sum(np.asarray(result) != 0)),
            "max_residual": float(np.max(np.asarray(res))),
            "newton_iterations_min_max": [int(np.min(steps)), int(np.max(steps))],
        }
    return out


def ms(s):
    return f"{1e3 * s:9.2f} ms"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--quick", action="store_true", help="fewer repeats, 256-solve batch"
    )
    ap.add_argument("--batch", type=int, default=None, help="batch size (default 1024)")
    ap.add_argument(
        "--chunk", type=int, default=64, help="lax.map batch_size variant (0: skip it)"
    )
    args = ap.parse_args(argv)
    repeats = 3 if args.quick else 9
    # One 1024-solve batch call takes ~10-20 s on a 2-core CPU, hence fewer repeats.
    batch_repeats = 1 if args.quick else 3
    n_batch = args.batch or (256 if args.quick else 1024)
    n_loop = 32

    env = environment()
    print(
        f"jax {env['jax_version']} on {env['devices']}, {env['cpu_count']} CPUs,"
        f" load average {env['load_average_at_start'][0]:.1f}"
    )
    t_start = time.perf_counter()

    kin = bench_kinematics(repeats)
    print(
        f"\n[1] Kinematics, {kin['n_dof']}-DoF rod (modes {MODES_12}, order {ORDER_12})"
    )
    print(f"    {'function':<22}{'compile':>14}{'warm (AOT)':>14}{'warm (call)':>14}")
    for name in ("forward_kinematics", "jacobians"):
        k = kin[name]
        print(
            f"    {name:<22}{k['compile_s']:>12.2f} s{ms(k['warm_median_s']):>14}"
            f"{ms(k['warm_median_via_filter_jit_call_s']):>14}"
        )

    st = bench_single_statics(repeats)
    print(
        f"\n[2] Statics, {st['n_dof']}-DoF rod, P L^2/EI = {st['alpha_y']} (y)"
        f" + {st['alpha_z']} (z)"
    )
    print(f"    compile            {st['compile_s']:8.2f} s")
    print(f"    warm (median)      {ms(st['warm_median_s'])}")
    print(f"    warm, public API   {ms(st['public_solve_statics_warm_median_s'])}")
    print(f"    Newton iterations  {st['newton_iterations']}")
    print(
        f"    residual (max)     {st['residual_max_norm']:.2e}  result {st['result_code']}"
    )
    print(f"    tip position [m]   {np.round(st['tip_position_m'], 4).tolist()}")
    print(
        f"    SoRoSim 0.5 s / ours = {st['sorosim_ratio']:.0f}x"
        f"   (target warm < 20 ms: {'met' if st['warm_median_s'] < 0.02 else 'NOT met'})"
    )

    ba = bench_batch(n_batch, n_loop, repeats, batch_repeats, args.chunk)
    lp = ba["loop"]
    print(f"\n[3] {n_batch} statics solves, P L^2/EI in [0.5, 5]")
    print(
        f"    {'method':<26}{'compile':>10}{'total':>12}{'per solve':>13}{'solves/s':>10}{'speedup':>9}"
    )
    print(
        f"    {'one at a time (loop)':<26}{'-':>10}{lp['extrapolated_total_s']:>10.2f} s"
        f"{ms(lp['per_solve_s']):>13}{lp['solves_per_s']:>10.0f}{1.0:>8.2f}x"
    )
    for name in [k for k in ba if k.startswith(("vmap", "lax.map"))]:
        v = ba[name]
        print(
            f"    {name:<26}{v['compile_s']:>8.1f} s{v['warm_median_s']:>10.2f} s"
            f"{ms(v['per_solve_s']):>13}{v['solves_per_s']:>10.0f}{v['speedup_vs_loop']:>8.2f}x"
            f"   failed {v['n_failed']}, iters {v['newton_iterations_min_max']}"
        )
    print("    (loop: 32 solves timed and extrapolated; target speedup >= 10x)")

    total = time.perf_counter() - t_start
    print(f"\nTotal benchmark time {total:.0f} s")
    RESULTS_DIR.mkdir(parents=True, exist_ok=True)
    out = {
        "environment": env,
        "settings": {
            "quick": args.quick,
            "repeats": repeats,
            "batch_repeats": batch_repeats,
            "rod": {"L": L, "r": R, "E": E, "I": I},
        },
        "kinematics_12dof": kin,
        "statics_30dof": st,
        "batched_statics": ba,
        "total_benchmark_s": total,
        "load_average_at_end": list(os.getloadavg()),
    }
    path = RESULTS_DIR / "statics.json"
    path.write_text(json.dumps(out, indent=2, default=lambda o: list(o)))
    print(f"Wrote {path}")


if __name__ == "__main__":
    main()
