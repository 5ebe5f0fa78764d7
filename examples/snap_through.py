"""Snap-through and buckling: equilibrium paths through folds and bifurcations.

Left: the von Mises truss (``sorojax.scenes.von_mises_truss``: two extensible bars
pinned to the ground and to each other, a downward force F on the apex). Its
equilibrium path, traced by ``sorojax.continuation`` in the load factor F / F_max,
rises to a fold (limit point) at F_max, runs back through unstable equilibria past
the flat position to a second fold at -F_max and ends on the inverted, stable
branch. Over it, the plain load sweep a user would write: ``solve_statics`` at 16
loads from 0 to 1.5 F_max, each warm-started from the previous solution. Newton's
method stalls at the fold itself (the tangent stiffness is singular there: the
residual is at round-off but the step does not shrink) and past it jumps: from that
singular start, at 1.1 F_max it converges to an *unstable* equilibrium with the apex
at the flat height but not on the symmetric path (bar 1 horizontal and stretched to
twice its length, bar 2 squashed to 3 % of its own, the apex just past bar 2's
ground pin: the bars are linear springs), which ``StaticsSolution.stable`` flags
(red crosses). Where the sweep lands past a fold depends on its steps (with 17
loads it snaps to the inverted, stable branch); continuation does not guess.

Right: Euler's elastica (``sorojax.scenes.pinned_elastica``, pinned-pinned, order 8).
Continuation with ``switch_branch=True`` finds the bifurcation at P / P_cr = 1 and
follows the buckled branch, which lies on the exact curve P / P_cr =
(2 K(sin(alpha / 2)) / pi)^2 of the end rotation alpha (thin line); a second run
without switching stays on the straight branch, unstable above P_cr (dashed).

Run::

    python examples/snap_through.py [--out DIR] [--overwrite]
"""

import argparse
import math
import pathlib
import time

import jax

jax.config.update("jax_enable_x64", True)

import matplotlib  # noqa: E402
import numpy as np  # noqa: E402
from scipy.special import ellipk  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import sorojax as sj  # noqa: E402
from sorojax.scenes import pinned_elastica, von_mises_truss  # noqa: E402
from sorojax.viz import plot_equilibrium_path  # noqa: E402

sj.set_runtime_flags()  # XLA's CPU runtime flags: before any JAX array exists

P_END = 1.5  # last load factor of the truss (path and sweep)
P_END_ELASTICA = 1.3  # last P / P_cr of the elastica (end rotation ~80 degrees)


def apex_height(linkage, q) -> float:
    """Height of the truss apex (tip of bar 1) [m]."""
    return float(sj.tip_pose(linkage, q)[1, 3])


def elastica_load(alpha):
    """Exact P / P_cr of the pinned-pinned elastica at end rotation ``alpha`` [rad]."""
    return (2.0 * ellipk(np.sin(np.asarray(alpha) / 2.0) ** 2) / math.pi) ** 2


def truss_sweep(loads):
    """Plain ``solve_statics`` at each load factor, warm-started from the previous q.

    Returns ``(q, converged, stable)`` arrays over the loads.
    """
    lk, _ = von_mises_truss()
    q = np.zeros(lk.n_dof)
    qs, converged, stable = [], [], []
    for f in loads:
        lk_f, _ = von_mises_truss(load_factor=float(f))  # same structure: one compile
        sol = sj.solve_statics(lk_f, q, throw=False, warn_unstable=False)
        q = np.asarray(sol.q)
        qs.append(q)
        converged.append(bool(sol.result == sj.RESULTS.successful))
        stable.append(bool(sol.stable))
    return np.asarray(qs), np.asarray(converged), np.asarray(stable)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=16, help="loads of the plain sweep")
    ap.add_argument("--order", type=int, default=8, help="Legendre order, elastica")
    ap.add_argument("--out", default=".", help="folder for the PNG")
    ap.add_argument("--overwrite", action="store_true", help="replace an old PNG")
    args = ap.parse_args(argv)
    sj.enable_compilation_cache()  # later runs load the compiled programs
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    png = out / "snap_through.png"
    if png.exists() and not args.overwrite:
        raise SystemExit(f"{png} exists; pass --overwrite to replace it")

    # The later programs (the plain sweep's solve and the elastica's corrector)
    # compile in a worker thread while the truss's path is traced (sorojax.prepare:
    # the calls' arguments, values aside).
    truss, F_max = von_mises_truss()
    column = pinned_elastica(args.order)
    sj.prepare(sj.solve_statics, truss, np.zeros(truss.n_dof), warn_unstable=False)
    sj.prepare(sj.continuation, column, 0.0, P_END_ELASTICA, switch_branch=True)

    # ------------------------------------------------------------ von Mises truss
    t0 = time.perf_counter()
    path = sj.continuation(truss, 0.0, P_END)
    t_path = time.perf_counter() - t0
    folds = [c.p for c in path.limit_points]
    # analytic apex height at the fold: y* = sqrt(a^(4/3) l^(2/3) - a^2)
    a, length = 0.3 * math.cos(math.radians(15.0)), 0.3
    y_star = math.sqrt(a ** (4 / 3) * length ** (2 / 3) - a**2)
    y_folds = [apex_height(truss, c.q) for c in path.limit_points]
    print(
        f"truss: {len(path.p)} points, {path.num_corrections} corrector runs, "
        f"{t_path:.2f} s, {path.status}"
    )
    for p, y, ref in zip(folds, y_folds, (1.0, -1.0), strict=False):
        print(
            f"  fold at F/F_max = {p:+.12f} (analytic {ref:+.0f}, error "
            f"{abs(p - ref):.1e}); apex {1e3 * y:+.3f} mm (analytic "
            f"{1e3 * math.copysign(y_star, y):+.3f} mm)"
        )

    loads = np.linspace(0.0, P_END, args.steps)
    t0 = time.perf_counter()
    q_sweep, converged, stable = truss_sweep(loads)
    t_sweep = time.perf_counter() - t0
    y_sweep = np.asarray([apex_height(truss, q) for q in q_sweep])
    print(
        f"plain sweep: {args.steps} solve_statics, {t_sweep:.2f} s; "
        f"{int((~converged).sum())} not converged, "
        f"{int((converged & ~stable).sum())} converged to unstable equilibria"
    )
    for f, q, c, s in zip(loads, q_sweep, converged, stable, strict=True):
        if not (c and s):
            state = "UNSTABLE" if c else "not converged"
            apex = np.asarray(sj.tip_pose(truss, q))[:2, 3]
            print(
                f"  F/F_max = {f:.2f}: {state}, apex ({1e3 * apex[0]:.1f}, "
                f"{1e3 * apex[1]:+.3f}) mm (symmetric: x = {1e3 * a:.1f} mm), "
                f"bar strains {q[1]:+.3f} {q[3]:+.3f}"
            )

    # ------------------------------------------------------------------ elastica
    t0 = time.perf_counter()
    buckled = sj.continuation(column, 0.0, P_END_ELASTICA, switch_branch=True)
    t_buckled = time.perf_counter() - t0
    t0 = time.perf_counter()
    straight = sj.continuation(column, 0.0, P_END_ELASTICA)
    t_straight = time.perf_counter() - t0
    (bif,) = buckled.bifurcations
    # the path vs the closed form, away from the bifurcation (alpha > 2 degrees)
    on = (buckled.branch == 1) & (np.abs(buckled.q[:, 0]) > math.radians(2))
    alpha = np.abs(buckled.q[on, 0])
    exact = elastica_load(alpha)
    err = float(np.max(np.abs(buckled.p[on] - exact) / exact))
    print(
        f"elastica (order {args.order}, {column.n_dof} DoF): bifurcation at "
        f"P/P_cr = {bif.p:.7f} (Euler: 1, error {abs(bif.p - 1):.1e})"
    )
    print(
        f"  buckled branch: {int(on.sum())} points up to "
        f"{math.degrees(alpha.max()):.1f} deg, max relative error of P/P_cr vs "
        f"elliptic integrals {err:.1e}"
    )
    print(
        f"  corrector runs {buckled.num_corrections} (switching, {t_buckled:.2f} s) "
        f"+ {straight.num_corrections} (straight, {t_straight:.2f} s)"
    )

    # ------------------------------------------------------------------- figure
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4.3))
    plot_equilibrium_path(
        path,
        lambda q: 1e3 * apex_height(truss, q),
        ax=a1,
        label="continuation",
        color="tab:blue",
    )
    groups = (
        (converged & stable, "o", "k", "solve_statics sweep: stable"),
        (converged & ~stable, "x", "tab:red", "sweep: UNSTABLE (apex past far pin)"),
        (~converged, "s", "tab:gray", "sweep: not converged (fold)"),
    )
    for mask, marker, color, label in groups:
        if mask.any():
            a1.plot(
                loads[mask],
                1e3 * y_sweep[mask],
                marker,
                color=color,
                markerfacecolor="none" if marker != "x" else color,
                markersize=7,
                mew=1.5,
                linestyle="none",
                label=label,
            )
    a1.axvline(1.0, color="0.7", lw=0.8, zorder=0)
    a1.set_xlabel("F / F_max")
    a1.set_ylabel("apex height [mm]")
    a1.set_title("von Mises truss: snap-through (folds at +-F_max)")
    a1.legend(fontsize=8, loc="center right", bbox_to_anchor=(1.0, 0.33))
    a1.grid(alpha=0.3)

    a_ex = np.linspace(0.0, math.radians(85.0), 300)
    p_ex = elastica_load(a_ex)
    keep = p_ex <= P_END_ELASTICA
    for sign, label in ((1, "exact elastica"), (-1, None)):
        a2.plot(
            p_ex[keep],
            sign * np.degrees(a_ex[keep]),
            color="k",
            lw=0.7,
            label=label,
        )
    plot_equilibrium_path(straight, 0, ax=a2, label="straight branch", color="tab:gray")
    plot_equilibrium_path(
        buckled,
        lambda q: math.degrees(q[0]),
        ax=a2,
        label="continuation, switch_branch",
        color="tab:orange",
    )
    a2.set_xlabel("P / P_cr")
    a2.set_ylabel("end rotation [deg]")
    a2.set_title("pinned-pinned elastica: bifurcation at P_cr")
    a2.legend(fontsize=8, loc="upper left")
    a2.grid(alpha=0.3)
    fig.suptitle("sorojax.continuation: solid stable, dashed unstable")
    fig.tight_layout()
    fig.savefig(png, dpi=110)
    plt.close(fig)
    print(f"wrote {png}")
    return {
        "folds": folds,
        "fold_apex_heights": y_folds,
        "fold_apex_height_analytic": y_star,
        "sweep_loads": loads,
        "sweep_apex_heights": y_sweep,
        "sweep_converged": converged,
        "sweep_stable": stable,
        "bifurcation": bif.p,
        "elastica_max_relative_error": err,
        "paths": {"truss": path, "buckled": buckled, "straight": straight},
    }


if __name__ == "__main__":
    main()
