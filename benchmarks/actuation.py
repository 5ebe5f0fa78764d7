"""Speed benchmark: actuated and closed-loop models (cables, prescribed joints, loops).

Run from the repository root::

    .venv/bin/python benchmarks/actuation.py            # both parts
    .venv/bin/python benchmarks/actuation.py --quick    # fewer repeats, 250-set batch
    .venv/bin/python benchmarks/actuation.py --part cables   # or --part hybrid

Parts (compile time, ``jax.jit(f).lower(...).compile()``, reported separately from
warm time; warm figures are medians of repeated calls after a warm-up, each ended with
``jax.block_until_ready``):

1. ``cables``: the four-cable manipulator (``sorojax._mechanisms.cable_manipulator``,
   12 DoF: bending about y and z, Legendre order 2 in each of its two divisions,
   hanging under gravity, oblique cable paths) solved for 1000 tension sets drawn
   uniformly from [0, 15] N per cable (seed 0), with ``solve_statics(throw=False)``:
   one at a time (a Python loop over a jitted single solve; ``--n-loop`` sets timed,
   repeated, extrapolated), ``jax.vmap`` over all sets at once, and
   ``jax.lax.map(batch_size=--chunk)`` (vmap in chunks); then the loop, vmap and
   lax.map again with ``load_steps=1`` (one load increment for every set: no load
   probe, and no vmapped member waits for another's extra increments).
2. ``hybrid``: the manual's hybrid closed-chain scene (``sorojax.scenes.
   manual_hybrid``, 17 DoF, one fixed closed-loop joint, a prescribed revolute and a
   cable): statics at angle -pi/4 and 50 N from the straight configuration, then
   5 s of dynamics from the rest equilibrium with the revolute at pi t / 2 and the
   tension ramped to 50 N over the first second (the inputs of
   examples/manual_hybrid.py), with ``simulate``'s ``"auto"`` solver at the example's
   rtol 1e-6, atol 1e-8. The scene is imported when this part runs (it runs last).

Prints tables and writes ``benchmarks/results/actuation.json`` and
``benchmarks/results/actuation.csv``.
"""

import argparse
import csv
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

import sorojax as sj  # noqa: E402
from sorojax._mechanisms import cable_manipulator  # noqa: E402
from sorojax.scenes import manual_hybrid_inputs  # noqa: E402

RESULTS_DIR = Path(__file__).resolve().parent / "results"
T_MAX = 15.0  # tensions drawn from [0, T_MAX] N per cable
ORDER = 2  # Legendre order of the arm's divisions (12 DoF)
HYBRID_ANGLE, HYBRID_TENSION, HYBRID_T1 = -math.pi / 4, 50.0, 5.0


def jit(f):
    """``jax.jit`` with sorojax's XLA options (what its own entry points compile
    with; JAX takes them on top-level jits only)."""
    return jax.jit(f, compiler_options=sj.compiler_options())


# ------------------------------------------------------------------------ cables
def bench_cables(n_batch, n_loop, repeats, batch_repeats, chunk):
    arm = cable_manipulator(order=ORDER)
    tip_point = arm.tip_point(1)
    rng = np.random.default_rng(0)
    tensions = jnp.asarray(rng.uniform(0.0, T_MAX, size=(n_batch, arm.n_inputs)))

    def solve_one(T, load_steps=None):
        sol = sj.solve_statics(arm, u=T, throw=False, load_steps=load_steps)
        tip = sj.forward_kinematics(arm, sol.q)[tip_point, :3, 3]
        return tip, sol.residual_norm, sol.num_steps, sol.result._value

    def solve_one_ls1(T):
        return solve_one(T, load_steps=1)

    out = {
        "n_dof": arm.n_dof,
        "order": ORDER,
        "n_batch": n_batch,
        "tension_range_N": [0.0, T_MAX],
    }
    single = jit(solve_one)
    compiled, tc = compile_time(single, tensions[0])
    med, best = timed(compiled, tensions[0], repeats=repeats)
    idx = np.linspace(0, n_batch - 1, n_loop).astype(int)
    sub = [tensions[i] for i in idx]

    def loop():
        return [compiled(T)[0] for T in sub]

    med_loop, best_loop = timed(loop, repeats=repeats)
    per = med_loop / n_loop
    steps = [int(compiled(T)[2]) for T in sub]
    # The public call path: filter_jit dispatch with a concrete linkage.
    t0 = time.perf_counter()
    jax.block_until_ready(sj.solve_statics(arm, u=tensions[0]).q)
    first_public = time.perf_counter() - t0
    med_pub, _ = timed(lambda: sj.solve_statics(arm, u=tensions[0]).q, repeats=repeats)
    out["single"] = {
        "compile_s": tc,
        "warm_median_s": med,
        "warm_min_s": best,
        "public_first_call_s": first_public,
        "public_warm_median_s": med_pub,
    }
    out["loop"] = {
        "n_timed": n_loop,
        "repeats": repeats,
        "time_for_n_timed_median_s": med_loop,
        "time_for_n_timed_min_s": best_loop,
        "per_solve_s": per,
        "solves_per_s": 1.0 / per,
        "extrapolated_total_s": per * n_batch,
        "newton_iterations_min_max": [min(steps), max(steps)],
    }
    # One increment for every set (load_steps=1): no load probe, and under vmap no
    # member waits for another's extra increment. All sets converge without
    # increments here (checked below: n_failed); the loop is timed again with it.
    compiled_ls1, _ = compile_time(jit(solve_one_ls1), tensions[0])
    med_ls1, _ = timed(lambda: [compiled_ls1(T)[0] for T in sub], repeats=repeats)
    out["loop_load_steps_1"] = {
        "per_solve_s": med_ls1 / n_loop,
        "solves_per_s": n_loop / med_ls1,
        "speedup_vs_loop": per * n_loop / med_ls1,
    }
    variants = [("vmap", jit(jax.vmap(solve_one)))]
    if chunk:
        variants.append(
            (
                f"lax.map(batch_size={chunk})",
                jit(lambda T: jax.lax.map(solve_one, T, batch_size=chunk)),
            )
        )
    variants.append(("vmap, load_steps=1", jit(jax.vmap(solve_one_ls1))))
    if chunk:
        variants.append(
            (
                f"lax.map(batch_size={chunk}), load_steps=1",
                jit(lambda T: jax.lax.map(solve_one_ls1, T, batch_size=chunk)),
            )
        )
    for name, fn in variants:
        compiled_b, tcb = compile_time(fn, tensions)
        tips, res, steps_b, result = jax.block_until_ready(compiled_b(tensions))
        medb, bestb = timed(compiled_b, tensions, repeats=batch_repeats, warmup=False)
        out[name] = {
            "compile_s": tcb,
            "warm_median_s": medb,
            "warm_min_s": bestb,
            "repeats": batch_repeats,
            "per_solve_s": medb / n_batch,
            "solves_per_s": n_batch / medb,
            "speedup_vs_loop": per * n_batch / medb,
            "n_failed": int(np.sum(np.asarray(result) != 0)),
            "max_residual": float(np.max(np.asarray(res))),
            "newton_iterations_min_max": [int(np.min(steps_b)), int(np.max(steps_b))],
        }
        # The batched answers must be the loop's.
        loop_tips = np.stack([np.asarray(compiled(T)[0]) for T in sub])
        out[name]["max_tip_difference_vs_loop_m"] = float(
            np.abs(np.asarray(tips)[idx] - loop_tips).max()
        )
        out[name]["tip_range_m"] = [
            np.asarray(tips).min(axis=0).tolist(),
            np.asarray(tips).max(axis=0).tolist(),
        ]
    return out


# ------------------------------------------------------------------------ hybrid
# revolute angle pi t / 2 and tension ramped (1 - cos) to 50 N over 1 s
hybrid_inputs = manual_hybrid_inputs


def bench_hybrid(repeats, dyn_repeats):
    from sorojax.scenes import manual_hybrid

    linkage = manual_hybrid()
    q_ref = jnp.zeros(linkage.n_dof)
    u_st = jnp.array([HYBRID_ANGLE, HYBRID_TENSION])

    def statics(q0, u):
        sol = sj.solve_statics(linkage, q0, u=u, throw=False)
        return (
            sol.q,
            sol.residual_norm,
            sol.num_steps,
            sol.result._value,
            sol.constraint_error,
            sol.efforts,
        )

    compiled, tc = compile_time(jit(statics), q_ref, u_st)
    q, res, steps, result, cerr, eff = jax.block_until_ready(compiled(q_ref, u_st))
    med, best = timed(compiled, q_ref, u_st, repeats=repeats)
    out = {
        "n_dof": linkage.n_dof,
        "n_inputs": linkage.n_inputs,
        "n_constraints": linkage.n_constraints,
        "statics": {
            "inputs": [HYBRID_ANGLE, HYBRID_TENSION],
            "compile_s": tc,
            "warm_median_s": med,
            "warm_min_s": best,
            "repeats": repeats,
            "newton_iterations": int(steps),
            "residual_max_norm": float(res),
            "constraint_error": float(cerr),
            "result_code": int(result),
            "revolute_torque_Nm": float(eff[0]),
            "tip_link5_m": np.asarray(sj.tip_pose(linkage, q, 5))[:3, 3].tolist(),
        },
    }
    rest = compiled(q_ref, jnp.zeros(2))[0]

    # q0 is closed over (concrete), so simulate's "auto" analyses the model as in an
    # ordinary call.
    def dynamics():
        tr = sj.simulate(
            linkage,
            HYBRID_T1,
            rest,
            u=hybrid_inputs,
            rtol=1e-6,
            atol=1e-8,
            throw=False,
        )
        return tr, jnp.max(jnp.abs(tr.closure_errors(linkage)))

    compiled_d, tcd = compile_time(jit(dynamics))
    tr, drift = jax.block_until_ready(compiled_d())
    medd, bestd = timed(compiled_d, repeats=dyn_repeats, warmup=False)
    out["dynamics"] = {
        "t1_s": HYBRID_T1,
        "solver": tr.solver,
        "rtol_atol": [1e-6, 1e-8],
        "compile_s": tcd,
        "warm_median_s": medd,
        "warm_min_s": bestd,
        "repeats": dyn_repeats,
        "num_steps": int(tr.num_steps),
        "num_rejected_steps": int(tr.num_rejected_steps),
        "result_code": int(tr.result._value),
        "max_closure_error": float(drift),
        "revolute_torque_at_t1_Nm": float(tr.efforts[-1, 0]),
        "real_time_factor": HYBRID_T1 / medd,
    }
    return out


# -------------------------------------------------------------------------- main
def ms(s):
    return f"{1e3 * s:9.2f} ms"


def csv_rows(results):
    rows = []
    ca = results.get("cables")
    if ca:
        rows.append(
            {
                "part": "cables",
                "item": "single solve",
                "compile_s": ca["single"]["compile_s"],
                "warm_median_s": ca["single"]["warm_median_s"],
                "per_solve_s": ca["single"]["warm_median_s"],
                "solves_per_s": 1.0 / ca["single"]["warm_median_s"],
            }
        )
        lp = ca["loop"]
        rows.append(
            {
                "part": "cables",
                "item": f"loop ({lp['n_timed']} timed)",
                "warm_median_s": lp["time_for_n_timed_median_s"],
                "per_solve_s": lp["per_solve_s"],
                "solves_per_s": lp["solves_per_s"],
                "speedup_vs_loop": 1.0,
            }
        )
        for k in [k for k in ca if k.startswith(("vmap", "lax.map"))]:
            v = ca[k]
            rows.append(
                {
                    "part": "cables",
                    "item": f"{k} x {ca['n_batch']}",
                    "compile_s": v["compile_s"],
                    "warm_median_s": v["warm_median_s"],
                    "per_solve_s": v["per_solve_s"],
                    "solves_per_s": v["solves_per_s"],
                    "speedup_vs_loop": v["speedup_vs_loop"],
                    "n_failed": v["n_failed"],
                }
            )
    hy = results.get("hybrid")
    if hy:
        for k in ("statics", "dynamics"):
            rows.append(
                {
                    "part": "hybrid",
                    "item": k,
                    "compile_s": hy[k]["compile_s"],
                    "warm_median_s": hy[k]["warm_median_s"],
                }
            )
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer repeats, smaller batch")
    ap.add_argument("--part", choices=("all", "cables", "hybrid"), default="all")
    ap.add_argument("--batch", type=int, default=None, help="tension sets (1000)")
    ap.add_argument("--n-loop", type=int, default=None, help="sets timed in the loop")
    ap.add_argument(
        "--chunk", type=int, default=50, help="lax.map batch_size variant (0: skip)"
    )
    args = ap.parse_args(argv)
    repeats = 3 if args.quick else 7
    batch_repeats = 1 if args.quick else 3
    dyn_repeats = 1 if args.quick else 3
    n_batch = args.batch or (250 if args.quick else 1000)
    n_loop = args.n_loop or (50 if args.quick else 100)

    env = environment()
    print(
        f"jax {env['jax_version']} on {env['devices']}, {env['cpu_count']} CPUs,"
        f" load average {env['load_average_at_start'][0]:.1f}",
        flush=True,
    )
    t_start = time.perf_counter()
    results = {}
    if args.part in ("all", "cables"):
        ca = bench_cables(n_batch, n_loop, repeats, batch_repeats, args.chunk)
        results["cables"] = ca
        s, lp = ca["single"], ca["loop"]
        print(
            f"\n[1] Four-cable arm ({ca['n_dof']} DoF), {n_batch} tension sets in "
            f"[0, {T_MAX:g}] N"
        )
        print(
            f"    single solve: compile {s['compile_s']:.1f} s, warm {ms(s['warm_median_s'])}"
            f" (public API {ms(s['public_warm_median_s'])})"
        )
        print(
            f"    {'method':<40}{'compile':>10}{'total':>12}{'per solve':>13}"
            f"{'solves/s':>10}{'speedup':>9}"
        )
        print(
            f"    {'one at a time (loop)':<40}{'-':>10}"
            f"{lp['extrapolated_total_s']:>10.2f} s{ms(lp['per_solve_s']):>13}"
            f"{lp['solves_per_s']:>10.0f}{1.0:>8.2f}x   iters "
            f"{lp['newton_iterations_min_max']}"
        )
        l1 = ca["loop_load_steps_1"]
        print(
            f"    {'loop, load_steps=1':<40}{'-':>10}"
            f"{l1['per_solve_s'] * n_batch:>10.2f} s{ms(l1['per_solve_s']):>13}"
            f"{l1['solves_per_s']:>10.0f}{l1['speedup_vs_loop']:>8.2f}x"
        )
        for name in [k for k in ca if k.startswith(("vmap", "lax.map"))]:
            v = ca[name]
            print(
                f"    {name:<40}{v['compile_s']:>8.1f} s{v['warm_median_s']:>10.2f} s"
                f"{ms(v['per_solve_s']):>13}{v['solves_per_s']:>10.0f}"
                f"{v['speedup_vs_loop']:>8.2f}x   failed {v['n_failed']}, iters "
                f"{v['newton_iterations_min_max']}, |tip - loop| "
                f"{v['max_tip_difference_vs_loop_m']:.1e} m",
                flush=True,
            )
    if args.part in ("all", "hybrid"):
        try:
            hy = bench_hybrid(repeats, dyn_repeats)
        except ImportError as err:  # the scene is not in this checkout yet
            print(f"\n[2] hybrid scene: skipped ({err})")
            results["hybrid"] = None
        else:
            results["hybrid"] = hy
            st, dy = hy["statics"], hy["dynamics"]
            print(
                f"\n[2] Manual hybrid scene ({hy['n_dof']} DoF, {hy['n_inputs']} "
                f"inputs, {hy['n_constraints']} loop rows)"
            )
            print(
                f"    statics (angle {HYBRID_ANGLE:.4f} rad, {HYBRID_TENSION:g} N): "
                f"compile {st['compile_s']:.1f} s, warm {ms(st['warm_median_s'])}, "
                f"{st['newton_iterations']} iterations, residual "
                f"{st['residual_max_norm']:.1e}, loop error "
                f"{st['constraint_error']:.1e}"
            )
            print(
                f"    dynamics {dy['t1_s']:g} s ({dy['solver']}): compile "
                f"{dy['compile_s']:.1f} s, warm {dy['warm_median_s']:.2f} s, "
                f"{dy['num_steps']} steps ({dy['num_rejected_steps']} rejected), "
                f"max loop error {dy['max_closure_error']:.1e}",
                flush=True,
            )

    total = time.perf_counter() - t_start
    print(f"\nTotal benchmark time {total:.0f} s")
    RESULTS_DIR.mkdir(parents=True, exist_ok=True)
    out = {
        "environment": env,
        "settings": {
            "quick": args.quick,
            "part": args.part,
            "repeats": repeats,
            "batch_repeats": batch_repeats,
            "dynamics_repeats": dyn_repeats,
            "xla_compiler_options": sj.compiler_options(),
        },
        **results,
        "total_benchmark_s": total,
        "load_average_at_end": list(os.getloadavg()),
    }
    path = RESULTS_DIR / "actuation.json"
    path.write_text(json.dumps(out, indent=2))
    rows = csv_rows(results)
    fields = [
        "part",
        "item",
        "compile_s",
        "warm_median_s",
        "per_solve_s",
        "solves_per_s",
        "speedup_vs_loop",
        "n_failed",
    ]
    with open(RESULTS_DIR / "actuation.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=fields)
        w.writeheader()
        w.writerows(rows)
    print(f"Wrote {path} and {RESULTS_DIR / 'actuation.csv'}")


if __name__ == "__main__":
    main()
