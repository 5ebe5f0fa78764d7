"""Accuracy benchmark: cantilever tip deflection versus the exact elastica.

Run from the repository root::

    .venv/bin/python benchmarks/convergence.py            # orders 2..10 (~3-4 min, 2 CPUs)
    .venv/bin/python benchmarks/convergence.py --quick    # orders 2, 4, 6, 8, 10, fewer repeats

A clamped rod (L = 1 m, r = 1 cm, E = 1e7 Pa) with only bending about z active
(modes (0, 0, 1, 0, 0, 0): inextensible, shearless, planar) carries a +y dead tip
force P with alpha = P L^2 / (E I) in {1, 2, 5, 10}. For each Legendre basis order
the static tip position from ``sorojax.solve_statics`` is compared with the
elliptic-integral (Bisshopp-Drucker) solution ``elastica_cantilever_tip_load`` in
``tests/references.py``. 4 load steps are used for alpha >= 5: by default as a
continuation (alpha/4, alpha/2, 3 alpha/4, alpha, each solve warm-started from the
last) that reuses the single compiled solve of that order, which is the scheme of
``solve_statics(load_steps=4)`` at half the compile cost; ``--native-load-steps``
calls ``solve_statics(load_steps=4)`` itself (a second compile per order).

Reported per (order, alpha): relative error of the tip deflection y_tip, relative
error of x_tip, absolute error of the tip rotation, Newton iterations, and the warm
time per solve (median of repeats of an AOT-compiled solve; compile time apart).
Writes ``benchmarks/results/convergence.csv``, ``convergence.json`` and
``convergence.png`` (log plot).
"""

import argparse
import csv
import json
import math
import os
import statistics
import sys
import time
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
from _common import git_state  # noqa: E402

import sorojax  # noqa: E402
from sorojax.scenes import cantilever  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))
from references import elastica_cantilever_tip_load  # noqa: E402

RESULTS_DIR = ROOT / "benchmarks" / "results"
L, R, E = 1.0, 0.01, 1e7
I = math.pi * R**4 / 4
MODES = (0, 0, 1, 0, 0, 0)  # bending about z only: +y tip force bends in x-y
ALPHAS = (1.0, 2.0, 5.0, 10.0)


def load_steps_for(alpha):
    return 4 if alpha >= 5 else 1


def make_solver(order, load_steps, n_gauss=None):
    """Jitted solve for one basis order; the load alpha and the start q0 are traced.

    With ``load_steps=None`` the returned function solves at the full load from ``q0``
    (one Newton solve); load stepping is then done by :func:`continuation`, reusing
    this one compiled function. Otherwise ``solve_statics(load_steps=...)`` is used.
    """

    def solve(alpha, q0):
        P = alpha * E * I / L**2
        rod = cantilever(
            L,
            R,
            E,
            modes=MODES,
            order=order,
            n_gauss=n_gauss,
            tip_wrench=jnp.array([0.0, 0.0, 0.0, 0.0, 1.0, 0.0]) * P,
        )
        sol = sorojax.solve_statics(rod, q0, load_steps=load_steps or 1, throw=False)
        g = sorojax.tip_pose(rod, sol.q)
        rot = jnp.arctan2(g[1, 0], g[0, 0])
        return (
            g[0, 3],
            g[1, 3],
            rot,
            sol.residual_norm,
            sol.num_steps,
            sol.result._value,
            sol.q,
        )

    return jax.jit(solve)


def continuation(compiled, alpha, n_dof, load_steps):
    """Load stepping with one compiled single-load solve: alpha k/n, k = 1..n, each
    warm-started from the last (the same scheme as ``solve_statics(load_steps=n)``)."""
    q = jnp.zeros(n_dof)
    steps = 0
    for k in range(1, load_steps + 1):
        *out, q = compiled(alpha * k / load_steps, q)
        steps = steps + out[4]
    out[4] = steps
    return (*out, q)


def timed(f, arg, repeats):
    ts = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(f(arg))
        ts.append(time.perf_counter() - t0)
    return statistics.median(ts)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="even orders only, 3 repeats")
    ap.add_argument("--orders", type=int, nargs="*", default=None)
    ap.add_argument(
        "--n-gauss",
        type=int,
        default=None,
        help="Gauss points per division (default: the library's)",
    )
    ap.add_argument(
        "--native-load-steps",
        action="store_true",
        help="use solve_statics(load_steps=4) for alpha >= 5 (one more "
        "compile per order) instead of the equivalent continuation",
    )
    args = ap.parse_args(argv)
    orders = args.orders or (
        list(range(2, 11, 2)) if args.quick else list(range(2, 11))
    )
    repeats = 3 if args.quick else 7

    refs = {a: elastica_cantilever_tip_load(a) for a in ALPHAS}
    print(
        f"jax {jax.__version__} on {jax.devices()}, {os.cpu_count()} CPUs,"
        f" load average {os.getloadavg()[0]:.1f}"
    )
    print("Reference (Bisshopp-Drucker) x_tip/L, y_tip/L, tip rotation:")
    for a, (x, y, th) in refs.items():
        print(f"  alpha = {a:4.1f}: {x:.10f}  {y:.10f}  {th:.10f}")

    rows = []
    t_start = time.perf_counter()
    for order in orders:
        n_dof = order + 1
        q0 = jnp.zeros(n_dof)
        solvers = {}
        for a in ALPHAS:
            ls = load_steps_for(a)
            key = None if not args.native_load_steps else ls
            if key not in solvers:
                t0 = time.perf_counter()
                compiled = make_solver(order, key, args.n_gauss).lower(a, q0).compile()
                solvers[key] = (compiled, time.perf_counter() - t0)
            compiled, tc = solvers[key]
            if key is None:

                def f(alpha, compiled=compiled, ls=ls, n_dof=n_dof):
                    return continuation(compiled, alpha, n_dof, ls)
            else:

                def f(alpha, compiled=compiled, q0=q0):
                    return compiled(alpha, q0)

            x, y, rot, res, steps, result, _ = jax.block_until_ready(f(a))
            warm = timed(f, a, repeats)
            xr, yr, thr = refs[a]
            rows.append(
                {
                    "order": order,
                    "n_dof": n_dof,
                    "alpha": a,
                    "load_steps": ls,
                    "x_tip": float(x) / L,
                    "y_tip": float(y) / L,
                    "rotation": float(rot),
                    "rel_err_y": abs(float(y) / L - yr) / abs(yr),
                    "rel_err_x": abs(float(x) / L - xr) / abs(xr),
                    "abs_err_rotation": abs(float(rot) - thr),
                    "newton_iterations": int(steps),
                    "residual_max_norm": float(res),
                    "result_code": int(result),
                    "warm_s": warm,
                    "compile_s": tc,
                }
            )
        print(
            f"  order {order:2d} done ({time.perf_counter() - t_start:5.0f} s)",
            flush=True,
        )

    # Tables.
    def table(title, key, fmt):
        print(f"\n{title}")
        print("  order  n_dof" + "".join(f"   alpha={a:<5g}" for a in ALPHAS))
        for order in orders:
            cells = [
                next(r for r in rows if r["order"] == order and r["alpha"] == a)
                for a in ALPHAS
            ]
            print(
                f"  {order:5d}  {order + 1:5d}"
                + "".join(f"{fmt(c[key]):>14}" for c in cells)
            )

    table(
        "Relative error of the tip deflection |y - y_ref| / y_ref:",
        "rel_err_y",
        lambda v: f"{v:.2e}",
    )
    table(
        "Absolute error of the tip rotation [rad]:",
        "abs_err_rotation",
        lambda v: f"{v:.2e}",
    )
    table(
        "Warm time per solve [ms] (load_steps = 4 for alpha >= 5):",
        "warm_s",
        lambda v: f"{1e3 * v:.2f}",
    )
    table(
        "Newton iterations (all load steps):", "newton_iterations", lambda v: f"{v:d}"
    )
    print(
        "\nCompile time per order [s] (per load_steps value with --native-load-steps):"
    )
    for order in orders:
        cs = {r["load_steps"]: r["compile_s"] for r in rows if r["order"] == order}
        if args.native_load_steps:
            print(
                f"  order {order:2d}: "
                + ", ".join(f"load_steps={k}: {v:.1f}" for k, v in cs.items())
            )
        else:
            print(f"  order {order:2d}: {next(iter(cs.values())):.1f}")
    bad = [r for r in rows if r["result_code"] != 0]
    if bad:
        print(
            f"\nWARNING: {len(bad)} solves did not report success: "
            + ", ".join(f"(order {r['order']}, alpha {r['alpha']})" for r in bad)
        )
    total = time.perf_counter() - t_start
    print(f"\nTotal {total:.0f} s")

    # Files.
    RESULTS_DIR.mkdir(parents=True, exist_ok=True)
    with open(RESULTS_DIR / "convergence.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    meta = {
        "jax_version": jax.__version__,
        "devices": [str(d) for d in jax.devices()],
        "cpu_count": os.cpu_count(),
        "load_average_at_end": list(os.getloadavg()),
        "git": git_state(),
        "repeats": repeats,
        "n_gauss": args.n_gauss,
        "native_load_steps": args.native_load_steps,
        "rod": {"L": L, "r": R, "E": E, "I": I, "modes": MODES},
        "references": {str(a): refs[a] for a in ALPHAS},
        "rows": rows,
        "total_s": total,
    }
    (RESULTS_DIR / "convergence.json").write_text(json.dumps(meta, indent=2))

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.2))
    for a in ALPHAS:
        rs = [r for r in rows if r["alpha"] == a]
        err = [max(r["rel_err_y"], 1e-17) for r in rs]
        ax1.semilogy([r["order"] for r in rs], err, "o-", label=f"$PL^2/EI$ = {a:g}")
        ax2.loglog(
            [1e3 * r["warm_s"] for r in rs], err, "o-", label=f"$PL^2/EI$ = {a:g}"
        )
    ax1.set_xlabel("Legendre basis order (n_dof = order + 1)")
    ax1.set_ylabel("relative error of tip deflection")
    ax1.set_title("Convergence vs elastica (Bisshopp-Drucker)")
    ax2.set_xlabel("warm time per solve [ms] (2-core CPU)")
    ax2.set_ylabel("relative error of tip deflection")
    ax2.set_title("Speed vs accuracy")
    for ax in (ax1, ax2):
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
    fig.tight_layout()
    fig.savefig(RESULTS_DIR / "convergence.png", dpi=120)
    print(f"Wrote {RESULTS_DIR / 'convergence.csv'}, convergence.json, convergence.png")


if __name__ == "__main__":
    main()
