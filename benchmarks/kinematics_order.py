"""Kinematics accuracy at high basis orders: the full-circle rod, error and cost.

Run from the repository root::

    .venv/bin/python benchmarks/kinematics_order.py            # orders 2..10, 5 repeats
    .venv/bin/python benchmarks/kinematics_order.py --quick    # orders 4, 8, 3 repeats
    .venv/bin/python benchmarks/kinematics_order.py --tag T         # results/..._T.*
    PYTHONPATH=/path/to/other/tree .venv/bin/python benchmarks/kinematics_order.py \
        --tag other                                    # another sorojax, same script

A clamped rod (L = 1 m, r = 1 cm, E = 1e7 Pa, poisson 0.5) with all six strain modes
active at Legendre order n (6 (n + 1) coordinates, one division, default ``n_gauss``)
carries a follower end moment M = 2 pi E I / L about z: the exact equilibrium is
the constant curvature 2 pi / L, a full circle with the tip back at the base, and
every basis represents it. For each order the static tip (``solve_statics`` then
``tip_pose``) is compared with the base; the distance / L measures how well the
kinematics integrate the high-order modes' Jacobian columns (the strain itself is
constant, so the poses are exact; only the generalised force J^T W can err).

Cost, for the same rods: compile time (trace + lower + compile, with sorojax's XLA
options) and warm time (median of ``--repeats`` calls after a warm-up) of one
``solve_statics`` and of one ``mass_matrix`` evaluation. Writes
``benchmarks/results/kinematics_order.csv`` and ``.json``, overwritten by a re-run
(``kinematics_order_<TAG>.*`` with ``--tag``). To compare two sorojax trees on a
shared machine, alternate tagged runs of each and compare pairs: the load moves
compile times by a second or more.
"""

import argparse
import csv
import json
import math
import sys
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
from _common import compile_time, environment, timed  # noqa: E402

import sorojax as sj  # noqa: E402

RESULTS_DIR = Path(__file__).resolve().parent / "results"
L, R, E = 1.0, 0.01, 1e7
EI = E * math.pi * R**4 / 4
M_CIRCLE = 2.0 * math.pi * EI / L  # curvature M / EI = 2 pi / L: one full turn


def circle_rod(order, modes=(1, 1, 1, 1, 1, 1), n_gauss=None, moment=M_CIRCLE):
    """The clamped rod under a follower end moment about z (``moment`` may be traced)."""
    div = sj.Division(
        L, sj.CircularSection(R), sj.LegendreBasis(modes, order), n_gauss=n_gauss
    )
    rod = sj.SoftLink([div], sj.Material(E, poisson=0.5))
    wrench = jnp.stack([0.0, 0.0, jnp.asarray(moment, float), 0.0, 0.0, 0.0])
    return sj.Linkage([rod], point_wrenches=[sj.PointWrench(1, wrench, follower=True)])


def tip_error(order, modes=(1, 1, 1, 1, 1, 1), n_gauss=None):
    """Distance of the static tip from the base, / L, and the Newton steps."""
    lk = circle_rod(order, modes, n_gauss)
    sol = sj.solve_statics(lk, warn_unstable=False)
    p = np.asarray(sj.tip_pose(lk, sol.q))[:3, 3]
    return float(np.linalg.norm(p)) / L, int(sol.num_steps), lk.n_dof


def costs(order, modes, repeats):
    """Compile and warm times of one statics solve and one mass-matrix evaluation."""
    opts = sj.compiler_options()

    def solve(moment):
        return sj.solve_statics(circle_rod(order, modes, moment=moment), throw=False).q

    m = jnp.asarray(M_CIRCLE)
    compiled, tc_s = compile_time(jax.jit(solve, compiler_options=opts), m)
    med_s, min_s = timed(compiled, m, repeats=repeats)
    lk = circle_rod(order, modes)
    q = compiled(m)

    def mass(q):
        return sj.mass_matrix(lk, q)

    compiled_m, tc_m = compile_time(jax.jit(mass, compiler_options=opts), q)
    med_m, min_m = timed(compiled_m, q, repeats=repeats)
    return {
        "statics_compile_s": tc_s,
        "statics_warm_median_s": med_s,
        "statics_warm_min_s": min_s,
        "mass_compile_s": tc_m,
        "mass_warm_median_s": med_m,
        "mass_warm_min_s": min_m,
    }


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="orders 4 and 8, 3 repeats")
    ap.add_argument("--orders", type=int, nargs="*", default=None)
    ap.add_argument("--repeats", type=int, default=None)
    ap.add_argument("--tag", default="", help="suffix of the result files")
    ap.add_argument(
        "--high-order",
        type=int,
        default=None,
        help="override the basis order from which 6th-order Magnus steps are used "
        "(sorojax.model._precompute.HIGH_ORDER; 0: every linkage), for comparisons",
    )
    args = ap.parse_args(argv)
    if args.high_order is not None:
        import sorojax.model._precompute as pre

        pre.HIGH_ORDER = args.high_order
    orders = args.orders or ([4, 8] if args.quick else list(range(2, 11)))
    repeats = args.repeats or (3 if args.quick else 5)
    rows = []
    for order in orders:
        err, steps, n_dof = tip_error(order)
        row = {"rod": "six modes", "order": order, "n_dof": n_dof}
        row |= {"tip_error_over_L": err, "newton_steps": steps}
        row |= costs(order, (1, 1, 1, 1, 1, 1), repeats)
        rows.append(row)
        print(json.dumps(row), flush=True)
    # The low-order reference: torsion and both bendings at order 3 (12 DoF).
    err, steps, n_dof = tip_error(3, (1, 1, 1, 0, 0, 0))
    row = {"rod": "bending+torsion", "order": 3, "n_dof": n_dof}
    row |= {"tip_error_over_L": err, "newton_steps": steps}
    row |= costs(3, (1, 1, 1, 0, 0, 0), repeats)
    rows.append(row)
    print(json.dumps(row), flush=True)
    RESULTS_DIR.mkdir(exist_ok=True)
    stem = "kinematics_order" + (f"_{args.tag}" if args.tag else "")
    with open(RESULTS_DIR / f"{stem}.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    env = environment(
        repeats=repeats,
        high_order_override=args.high_order,
        sorojax_imported_from=str(Path(sj.__file__).parent),
    )
    out = {"environment": env, "rows": rows}
    (RESULTS_DIR / f"{stem}.json").write_text(json.dumps(out, indent=1))
    print(f"wrote {RESULTS_DIR / stem}.csv/.json", file=sys.stderr)


if __name__ == "__main__":
    main()
