"""Speed benchmark: the stability report of statics and equilibrium-path continuation.

Run from the repository root::

    .venv/bin/python benchmarks/stability.py            # full run (9 repeats)
    .venv/bin/python benchmarks/stability.py --quick    # fewer repeats

Compile time (``jax.jit(f).lower(...).compile()``, sorojax's XLA options) is reported
separately from warm time; warm figures are the median (and minimum) of repeated
calls after a warm-up, each ended with ``jax.block_until_ready``.

1. *Added cost of the stability check per solve.* Every ``solve_statics`` now takes
   the spectrum of the tangent stiffness on the constraint manifold from its last
   Newton Jacobian (``reduced_tangent_spectrum`` + ``stability_summary``, no extra
   residual evaluation). Two 30-DoF cases:

   - ``open``: clamped rod, L 1 m, r 1 cm, E 1e7 Pa, bending about y and z
     (modes ``(0,1,1,0,0,0)``, Legendre order 14: 30 DoF), world-frame tip force
     P L^2 / (E I) = 5 along y and 0.5 along z, solved from the straight rod;
   - ``closed``: the clamped-clamped rod of tests/test_stability.py (L 0.4 m, r 5 mm,
     E 1e6 Pa, all six strain modes at order 4: 30 DoF, a fixed closed-loop joint at
     0.8 L: 6 rows), solved from its buckled guess (first clamped-clamped mode).

   Timed: the solve (jitted ``solve_statics``, linkage built inside from a traced
   load / closed over), and separately the jitted spectrum + summary on the *real*
   scaled Jacobian of that solve at its solution (``jax.jacfwd`` of the solver's
   Jacobi-scaled equilibrium rows ``scaled_equilibrium``, columns (q, multipliers):
   the same matrix, shape and constraint block as in the solve; the recomputed
   stable / n_negative / min_eigenvalue are checked against the solution's), and one
   evaluation of those rows and their Jacobian (what one Newton iteration
   evaluates). Ratio = spectrum / solve (target <= 20 %). Newton iterations per
   solve: ``num_steps``. Also the spectrum of that J made non-symmetric (a random
   skew part of 1e-3 of its largest entry added to the q-q block), the case of
   follower loads, which may take another code path.
2. *One continuation step vs one solve.* Whole ``sorojax.continuation`` runs,
   warm (the compiled corrector reused: the run after a first, compiling one), on
   ``scenes.euler_column(6)`` (0 -> 1.5 P_cr, ``switch_branch=True``),
   ``scenes.pinned_elastica(8)`` (0 -> 1.3 P_cr, ``switch_branch=True``) and
   ``scenes.von_mises_truss()`` (0 -> 1.5 F_max through both folds); per path point
   and per corrector run (``num_corrections``, which includes rejected steps and
   the location of critical points), against one jitted ``solve_statics`` of the
   same linkage at the path's last load from 0.9 x the path's last q (a few Newton
   iterations on the far branch). One more warm run is instrumented: the time inside
   the compiled corrector (wrapped, for that run, in the module where
   ``continuation`` looks it up) against the run's wall time, i.e. the share of the
   Python path loop on the host, and the mean Newton iterations per corrector run.
   Also the host-side ``stability_summary`` the path loop calls op by op after
   each corrector run.

Prints tables and writes ``benchmarks/results/stability.json`` and
``benchmarks/results/stability.csv`` (long format: part, case, quantity, value, unit).
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

import equinox as eqx  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
from _common import compile_time, environment, timed  # noqa: E402

import sorojax as sj  # noqa: E402
import sorojax.statics._continuation as _cont  # noqa: E402
from sorojax.dynamics._eom import as_inputs  # noqa: E402
from sorojax.model._precompute import precompute  # noqa: E402
from sorojax.scenes import (  # noqa: E402
    cantilever,
    euler_column,
    pinned_elastica,
    von_mises_truss,
)
from sorojax.statics._solve import (  # noqa: E402
    _row_scale,
    free_coordinates,
    scaled_equilibrium,
)
from sorojax.statics._stability import (  # noqa: E402
    reduced_tangent_spectrum,
    stability_summary,
)

RESULTS_DIR = Path(__file__).resolve().parent / "results"

# open case: the rod of benchmarks/statics.py, bending about y and z only
L, R, E = 1.0, 0.01, 1e7
EI_L2 = E * math.pi * R**4 / 4 / L**2
MODES_OPEN, ORDER_OPEN = (0, 1, 1, 0, 0, 0), 14  # 2 modes x 15 = 30 DoF
ALPHA, OUT_OF_PLANE = 5.0, 0.1
# closed case: tests/test_stability.py's clamped-clamped rod, order 4 (6 x 5 = 30 DoF)
E_C, R_C, L_C, ORDER_CLOSED = 1e6, 0.005, 0.4, 4


def jit(f):
    """``jax.jit`` with sorojax's XLA options (those of its own entry points)."""
    return jax.jit(f, compiler_options=sj.compiler_options())


def open_rod(alpha):
    P = alpha * EI_L2
    wrench = jnp.array([0.0, 0.0, 0.0, 0.0, 1.0, OUT_OF_PLANE]) * P
    return cantilever(L, R, E, modes=MODES_OPEN, order=ORDER_OPEN, tip_wrench=wrench)


def clamped_clamped():
    rod = sj.SoftLink(
        [
            sj.Division(
                L_C,
                sj.CircularSection(R_C),
                sj.LegendreBasis((1, 1, 1, 1, 1, 1), ORDER_CLOSED),
            )
        ],
        sj.Material(E_C),
    )
    return sj.Linkage(
        rod,
        closed_loops=[
            sj.ClosedLoopJoint(sj.Joint("N"), 1, 0, g_B=sj.translation(0.8 * L_C))
        ],
    )


def buckled_guess(lk):
    """First clamped-clamped mode at linear theory's amplitude (test_stability.py)."""
    a = math.sqrt(0.8) * L_C / math.pi
    k = 2 * math.pi / L_C

    def strain(s):
        return jnp.stack([0.0, 0.0, a / 2 * k**2 * jnp.cos(k * s), 1.0, 0.0, 0.0])

    return sj.strain_coordinates(lk, strain, total=True)


def scaled_rows(lk):
    """``x -> (scaled equilibrium rows, row scale)`` of the statics solver at full load.

    ``x = (q_free, mu)``; the rows are ``(scale * r_free, e)`` as in
    ``sorojax.statics._solve`` (no prescribed coordinates in these scenes).
    """
    data = precompute(lk)
    free = free_coordinates(lk)

    def rows(x):
        u = as_inputs(lk, None, x.dtype)
        f, _ = scaled_equilibrium(lk, data, x, jnp.zeros(()), 1.0, u, None)
        return f

    return rows, _row_scale(data.K)[free], len(free)


def spectrum_and_summary(J, scale, n_free):
    lam, _, n_man = reduced_tangent_spectrum(J, n_free, scale)
    return stability_summary(lam, n_man)


def bench_added_cost(repeats):
    out = {}
    cases = {
        "open": dict(lk=open_rod(ALPHA), q0=None),
        "closed": dict(lk=clamped_clamped(), q0=None),
    }
    cases["closed"]["q0"] = buckled_guess(cases["closed"]["lk"])
    for name, c in cases.items():
        lk = c["lk"]
        n = lk.n_dof
        q0 = jnp.zeros(n) if c["q0"] is None else jnp.asarray(c["q0"])

        # open: the linkage built inside from the traced load (as benchmarks/
        # statics.py); closed: closed over (its load is the loop's prescribed gap)
        build = open_rod if name == "open" else (lambda alpha, lk=lk: lk)

        def solve(alpha, q0, build=build):
            s = sj.solve_statics(build(alpha), q0, throw=False)
            return s.q, s.lam, s.num_steps, s.stable, s.n_negative, s.min_eigenvalue

        solve_args = (jnp.asarray(ALPHA), q0)
        compiled, tc_solve = compile_time(jit(solve), *solve_args)
        q, mu, steps, stable, n_neg, lam_min = jax.block_until_ready(
            compiled(*solve_args)
        )
        med_solve, min_solve = timed(compiled, *solve_args, repeats=repeats)

        rows, scale, n_free = scaled_rows(lk)
        free = free_coordinates(lk)
        x = jnp.concatenate([q[free], mu])
        jac = jit(jax.jacfwd(rows))
        jac_c, tc_jac = compile_time(jac, x)
        J = jax.block_until_ready(jac_c(x))
        med_jac, min_jac = timed(jac_c, x, repeats=repeats)

        spec = jit(lambda J_, s_, n_free=n_free: spectrum_and_summary(J_, s_, n_free))
        spec_c, tc_spec = compile_time(spec, J, scale)
        s2, n2, l2 = jax.block_until_ready(spec_c(J, scale))
        med_spec, min_spec = timed(spec_c, J, scale, repeats=max(repeats, 50))
        # the same J made non-symmetric (as follower loads make it): a skew part of
        # 1e-3 of the largest entry in the q-q block (other code path on CPU, when
        # the spectrum takes the general eigenvalues of a non-symmetric tangent)
        rng = np.random.default_rng(0)
        Rm = rng.normal(size=(n_free, n_free))
        skew = 1e-3 * float(jnp.max(jnp.abs(J))) * (Rm - Rm.T) / 2
        J_ns = J.at[:n_free, :n_free].add(jnp.asarray(skew))
        jax.block_until_ready(spec_c(J_ns, scale))
        med_ns, min_ns = timed(spec_c, J_ns, scale, repeats=max(repeats, 50))
        out[name] = {
            "n_dof": n,
            "n_constraints": lk.n_constraints,
            "jacobian_shape": list(J.shape),
            "solve": {
                "compile_s": tc_solve,
                "warm_median_s": med_solve,
                "warm_min_s": min_solve,
                "newton_iterations": int(steps),
                "stable": bool(stable),
                "n_negative": int(n_neg),
                "min_eigenvalue": float(lam_min),
            },
            "jacobian_evaluation": {
                "compile_s": tc_jac,
                "warm_median_s": med_jac,
                "warm_min_s": min_jac,
            },
            "spectrum_and_summary": {
                "compile_s": tc_spec,
                "warm_median_s": med_spec,
                "warm_min_s": min_spec,
                "matches_solution": bool(s2) == bool(stable)
                and int(n2) == int(n_neg)
                and abs(float(l2) - float(lam_min)) <= 1e-8 * max(1, abs(float(l2))),
            },
            "spectrum_and_summary_nonsymmetric_J": {
                "warm_median_s": med_ns,
                "warm_min_s": min_ns,
            },
            "ratio_spectrum_to_solve": med_spec / med_solve,
            "ratio_nonsymmetric_spectrum_to_solve": med_ns / med_solve,
            "ratio_spectrum_to_jacobian_evaluation": med_spec / med_jac,
        }
    return out


def scene_at(lk, p):
    """The linkage with its point wrench scaled by ``p`` (its load factor)."""
    return eqx.tree_at(
        lambda l_: l_.point_wrenches[0].wrench, lk, lk.point_wrenches[0].wrench * p
    )


def instrumented_run(run):
    """One warm run with the compiled corrector timed inside the path loop.

    ``continuation`` looks its corrector up in its module at call time, so it is
    wrapped here for this one run (blocked after each call; the loop converts its
    outputs to numpy right away, so this adds no wait). Returns the wall time, the
    time inside the corrector calls, their number and their Newton iterations.
    """
    orig = _cont._correct
    stats = {"corrector_s": 0.0, "calls": 0, "newton_iterations": 0}

    def wrapped(*args, **kwargs):
        t0 = time.perf_counter()
        out = jax.block_until_ready(orig(*args, **kwargs))
        stats["corrector_s"] += time.perf_counter() - t0
        stats["calls"] += 1
        stats["newton_iterations"] += int(out[2])
        return out

    _cont._correct = wrapped
    try:
        t0 = time.perf_counter()
        run()
        stats["wall_s"] = time.perf_counter() - t0
    finally:
        _cont._correct = orig
    stats["host_share"] = 1.0 - stats["corrector_s"] / stats["wall_s"]
    stats["iterations_per_call"] = stats["newton_iterations"] / stats["calls"]
    return stats


def bench_continuation(repeats):
    truss, _ = von_mises_truss()
    scenes = {
        "euler_column(6)": (euler_column(6), 1.5, True),
        "pinned_elastica(8)": (pinned_elastica(8), 1.3, True),
        "von_mises_truss()": (truss, 1.5, False),
    }
    out = {}
    for name, (lk, p1, switch) in scenes.items():

        def run(lk=lk, p1=p1, switch=switch):
            return sj.continuation(lk, 0.0, p1, switch_branch=switch)

        t0 = time.perf_counter()
        path = run()
        first = time.perf_counter() - t0
        ts = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            path = run()  # results are numpy arrays: already on the host
            ts.append(time.perf_counter() - t0)
        med, best = float(np.median(ts)), float(np.min(ts))

        # one solve of the same linkage at the path's last load, from 0.9 x its q
        lk_end = scene_at(lk, float(path.p[-1]))
        q0 = jnp.asarray(0.9 * path.q[-1])

        def solve(q0, lk_end=lk_end):
            s = sj.solve_statics(lk_end, q0, throw=False)
            return s.q, s.num_steps, s.result._value

        compiled, tc = compile_time(jit(solve), q0)
        q, steps, result = jax.block_until_ready(compiled(q0))
        med_solve, min_solve = timed(compiled, q0, repeats=max(repeats, 5))
        n_pts, n_corr = len(path.p), path.num_corrections
        corr = instrumented_run(run)
        out[name] = {
            "n_dof": lk.n_dof,
            "n_constraints": lk.n_constraints,
            "p1": p1,
            "switch_branch": switch,
            "status": path.status,
            "n_points": n_pts,
            "num_corrections": n_corr,
            "critical": [(c.kind, c.p) for c in path.critical],
            "first_run_s": first,
            "warm_median_s": med,
            "warm_min_s": best,
            "repeats": repeats,
            "per_point_s": med / n_pts,
            "per_correction_s": med / n_corr,
            "instrumented_run": corr,
            "solve": {
                "p": float(path.p[-1]),
                "compile_s": tc,
                "warm_median_s": med_solve,
                "warm_min_s": min_solve,
                "newton_iterations": int(steps),
                "result_code": int(result),
                "matches_path_point": bool(
                    np.allclose(np.asarray(q), path.q[-1], atol=1e-8)
                ),
            },
            "per_point_over_solve": med / n_pts / med_solve,
            "per_correction_over_solve": med / n_corr / med_solve,
        }

    # the host-side summary after each corrector run: op by op, as in the path loop
    lam = jnp.linspace(-1.0, 2.0, 11)
    n_man = jnp.asarray(11)

    def eager():
        return stability_summary(lam, n_man)

    med_eager, _ = timed(eager, repeats=max(repeats, 20))
    out["host_stability_summary_s"] = med_eager
    return out


def ms(s):
    return f"{1e3 * s:8.3f} ms"


def rows_for_csv(res):
    """Long-format rows ``(part, case, quantity, value, unit)`` of the results."""
    rows = []

    def add(part, case, quantity, value):
        rows.append(
            (part, case, quantity, value, "s" if quantity.endswith("_s") else "")
        )

    for case, r in res["added_cost"].items():
        for key in (
            "n_dof",
            "n_constraints",
            "ratio_spectrum_to_solve",
            "ratio_nonsymmetric_spectrum_to_solve",
        ):
            add("added_cost", case, key, r[key])
        for part in (
            "solve",
            "jacobian_evaluation",
            "spectrum_and_summary",
            "spectrum_and_summary_nonsymmetric_J",
        ):
            for key in ("compile_s", "warm_median_s", "warm_min_s"):
                if key in r[part]:
                    add("added_cost", case, f"{part}.{key}", r[part][key])
        add(
            "added_cost",
            case,
            "solve.newton_iterations",
            r["solve"]["newton_iterations"],
        )
    for case, r in res["continuation"].items():
        if not isinstance(r, dict):
            add("continuation", "host", "stability_summary_eager_s", r)
            continue
        for key in (
            "n_dof",
            "n_points",
            "num_corrections",
            "first_run_s",
            "warm_median_s",
            "per_point_s",
            "per_correction_s",
            "per_point_over_solve",
            "per_correction_over_solve",
        ):
            add("continuation", case, key, r[key])
        c = r["instrumented_run"]
        for key in ("wall_s", "corrector_s", "iterations_per_call", "host_share"):
            add("continuation", case, f"instrumented_run.{key}", c[key])
        add("continuation", case, "solve.warm_median_s", r["solve"]["warm_median_s"])
        add(
            "continuation",
            case,
            "solve.newton_iterations",
            r["solve"]["newton_iterations"],
        )
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer repeats")
    args = ap.parse_args(argv)
    repeats = 3 if args.quick else 9
    path_repeats = 2 if args.quick else 5

    env = environment()
    print(
        f"jax {env['jax_version']} on {env['devices']}, {env['cpu_count']} CPUs,"
        f" load average {env['load_average_at_start'][0]:.1f}"
    )
    t_start = time.perf_counter()

    added = bench_added_cost(repeats)
    print("\n[1] Stability check per solve (30 DoF)")
    print(
        f"    {'case':<8}{'J shape':>10}{'iters':>7}{'solve':>13}{'one J eval':>13}"
        f"{'spectrum':>13}{'/ solve':>9}{'/ J eval':>10}"
    )
    for name, r in added.items():
        print(
            f"    {name:<8}{'x'.join(map(str, r['jacobian_shape'])):>10}"
            f"{r['solve']['newton_iterations']:>7}"
            f"{ms(r['solve']['warm_median_s']):>13}"
            f"{ms(r['jacobian_evaluation']['warm_median_s']):>13}"
            f"{ms(r['spectrum_and_summary']['warm_median_s']):>13}"
            f"{100 * r['ratio_spectrum_to_solve']:>8.2f}%"
            f"{100 * r['ratio_spectrum_to_jacobian_evaluation']:>9.1f}%"
        )
        print(
            f"    {'':<8}non-symmetric J (follower-load path): "
            f"{ms(r['spectrum_and_summary_nonsymmetric_J']['warm_median_s'])}, "
            f"{100 * r['ratio_nonsymmetric_spectrum_to_solve']:.2f}% of the solve"
        )
        print(
            f"    {'':<8}compile: solve {r['solve']['compile_s']:.1f} s, spectrum "
            f"{r['spectrum_and_summary']['compile_s']:.2f} s; stable "
            f"{r['solve']['stable']}, n_negative {r['solve']['n_negative']}, "
            f"min eigenvalue {r['solve']['min_eigenvalue']:.3e}, recomputed "
            f"matches: {r['spectrum_and_summary']['matches_solution']}"
        )

    cont = bench_continuation(path_repeats)
    print("\n[2] Continuation (warm) vs one solve_statics")
    print(
        f"    {'scene':<20}{'dof':>4}{'points':>7}{'corr.':>6}{'first':>9}"
        f"{'warm':>10}{'/point':>12}{'/corr.':>12}{'solve':>12}{'it':>4}"
        f"{'pt/solve':>9}{'corr/solve':>11}"
    )
    for name, r in cont.items():
        if not isinstance(r, dict):
            continue
        print(
            f"    {name:<20}{r['n_dof']:>4}{r['n_points']:>7}{r['num_corrections']:>6}"
            f"{r['first_run_s']:>7.2f} s{r['warm_median_s']:>8.3f} s"
            f"{ms(r['per_point_s']):>12}{ms(r['per_correction_s']):>12}"
            f"{ms(r['solve']['warm_median_s']):>12}{r['solve']['newton_iterations']:>4}"
            f"{r['per_point_over_solve']:>8.2f}x{r['per_correction_over_solve']:>10.2f}x"
        )
    for name, r in cont.items():
        if isinstance(r, dict):
            c = r["instrumented_run"]
            print(
                f"    {name:<20}in the compiled corrector: "
                f"{c['corrector_s']:.3f} s of {c['wall_s']:.3f} s "
                f"({ms(c['corrector_s'] / c['calls'])} per call, "
                f"{c['iterations_per_call']:.2f} Newton iterations per call); "
                f"host {100 * c['host_share']:.0f} %"
            )
    print(
        f"    host-side stability_summary (op by op, per corrector run): "
        f"{ms(cont['host_stability_summary_s'])}"
    )

    total = time.perf_counter() - t_start
    print(f"\nTotal benchmark time {total:.0f} s")
    res = {
        "environment": env,
        "settings": {
            "quick": args.quick,
            "repeats": repeats,
            "path_repeats": path_repeats,
            "open": {
                "L": L,
                "r": R,
                "E": E,
                "modes": MODES_OPEN,
                "order": ORDER_OPEN,
                "alpha_y": ALPHA,
                "alpha_z": ALPHA * OUT_OF_PLANE,
            },
            "closed": {"L": L_C, "r": R_C, "E": E_C, "order": ORDER_CLOSED},
        },
        "added_cost": added,
        "continuation": cont,
        "total_benchmark_s": total,
        "load_average_at_end": list(os.getloadavg()),
    }
    RESULTS_DIR.mkdir(parents=True, exist_ok=True)
    path = RESULTS_DIR / "stability.json"
    path.write_text(json.dumps(res, indent=2, default=lambda o: list(o)))
    with open(RESULTS_DIR / "stability.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["part", "case", "quantity", "value", "unit"])
        w.writerows(rows_for_csv(res))
    print(f"Wrote {path} and stability.csv")


if __name__ == "__main__":
    main()
