"""Dynamics benchmark: accuracy, stability, speed and scaling of sorojax.simulate.

Run from the repository root::

    .venv/bin/python benchmarks/dynamics.py                 # all four parts
    .venv/bin/python benchmarks/dynamics.py --quick         # fewer points, shorter spans
    .venv/bin/python benchmarks/dynamics.py --part wp       # one part: wp | stability | speed | scaling

Parts (compile time reported separately from warm time; warm figures are medians of
repeated calls after a warm-up, each ended with ``jax.block_until_ready``):

1. ``wp``: work-precision on SoRoSim's free-fall rod (``sorojax.scenes.free_fall_rod``),
   undamped and damped (eta = 1e4 Pa s): tip-trajectory error (max over save times of
   |tip - tip_ref| / L) against Dopri8 at rtol 1e-12 with the same basis order, versus
   warm wall time, for each solver x rtol x Legendre order; plus the basis-order
   (discretisation) error, reference at order k against order 6.
2. ``stability``: the soft free-fall rod (undamped and damped), a stiff steel rod, and
   the soft rod falling onto a stiff floor (penalty contact, 1e7 N/m^2), each solver
   with constant steps h = 1e-2 .. 1e-5 and adaptive rtol 1e-3 / 1e-6: diverged / max
   steps / failed (a contact deeper than the rod's radius is failed) / ok, and wall
   time; the highest natural frequency from K v = w^2 M(q0) v (with the floor: the
   contact's sqrt(k / (rho A)) at the tip) and the explicit step limits it implies.
3. ``speed``: 5 s of the damped free-fall rod (12 DoF): compile and warm time of the
   default solver and of the two fastest solvers at an error of ~1e-4 (from part 1),
   against SoRoSim's 1.5 s (MATLAB, ode15s) and a 0.15 s target.
4. ``scaling``: wall time per simulated second against the number of DoF (6 .. 60), and
   per-simulation time of ``jax.vmap`` batches (1 .. 1024, over E) against one at a time.

Writes ``benchmarks/results/dynamics_*.{csv,png}`` and ``dynamics.json`` (a part run on
its own updates only its entry of the JSON).
"""

import argparse
import csv
import inspect
import json
import math
import os
import statistics
import time
from functools import partial
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import diffrax  # noqa: E402
import equinox as eqx  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
import scipy.linalg  # noqa: E402
from _common import environment as base_environment  # noqa: E402

import sorojax as sj  # noqa: E402
from sorojax.scenes import free_fall_q0, free_fall_rod  # noqa: E402

RESULTS_DIR = Path(__file__).resolve().parent / "results"
ROOT = Path(__file__).resolve().parent.parent

MODES = (1, 1, 1, 0, 0, 0)  # torsion + both bendings
L_SOFT = 0.5  # free-fall rod length [m]
ETA_DAMPED = 1e4  # Kelvin-Voigt damping of the damped case [Pa s]
N_SAVE = 101  # save times of every run (static: one compile serves all parts)
MAX_STEPS = 20_000  # step cap of adaptive runs (static: shared by parts 1, 3, 4)
STAB_MAX_STEPS = 4_000  # step cap of the adaptive runs of the stability part
DEFAULT_RTOL = inspect.signature(sj.simulate).parameters["rtol"].default
DEFAULT_ATOL = inspect.signature(sj.simulate).parameters["atol"].default
SOROSIM_5S_S = 1.5  # SoRoSim (MATLAB, ode15s): 5 s of the damped free-fall rod
SPEED_TARGET_S = 0.15

EXPLICIT = ("tsit5", "dopri5", "dopri8")
IMPLICIT = ("kvaerno3", "kvaerno5", "implicit_euler")
ROSENBROCK = ("ros34pw2",)  # linearly implicit (W = stiff part M, K, D): cheap steps
CONSTANT = ("rosenbrock_euler",)  # linearly implicit Euler: constant steps only
SOLVERS = EXPLICIT + IMPLICIT + ROSENBROCK + CONSTANT
WP_DTS = (1e-2, 3e-3, 1e-3, 3e-4, 1e-4)  # the constant-step solvers' steps [s]
STYLE = {  # colour, marker
    "tsit5": ("tab:blue", "o"),
    "dopri5": ("tab:orange", "s"),
    "dopri8": ("tab:green", "D"),
    "kvaerno3": ("tab:red", "^"),
    "kvaerno5": ("tab:purple", "v"),
    "implicit_euler": ("tab:brown", "P"),
    "ros34pw2": ("black", "*"),
    "rosenbrock_euler": ("tab:gray", "X"),
}


# --------------------------------------------------------------------------- utils


def environment():
    return base_environment(
        diffrax_version=diffrax.__version__,
        default_solver=sj.integrate.DEFAULT_SOLVER,
    )


def block(x):
    return jax.block_until_ready(x)


ONLY: tuple[str, ...] | None = None  # --solvers: run these, keep the others' rows


def run_solvers():
    """The solvers this run measures (all, or those of ``--solvers``)."""
    return [s for s in SOLVERS if ONLY is None or s in ONLY]


def merged_rows(new_rows, old_part):
    """With ``--solvers``: the new rows plus the previous run's rows of the others."""
    if ONLY is None or not old_part:
        return new_rows
    return [r for r in old_part.get("rows", []) if r["solver"] not in ONLY] + new_rows


def timed(fn, *, min_repeats=1, max_repeats=5, budget_s=1.0):
    """Warm timing: call ``fn()`` (already compiled) repeatedly, each call blocked.

    Repeats until ``max_repeats`` calls or until ``min_repeats`` calls have been made
    and ``budget_s`` seconds spent. Returns (last output, median, min, n calls).
    """
    ts, out = [], None
    while True:
        t0 = time.perf_counter()
        out = block(fn())
        ts.append(time.perf_counter() - t0)
        if len(ts) >= max_repeats or (len(ts) >= min_repeats and sum(ts) >= budget_s):
            return out, statistics.median(ts), min(ts), len(ts)


def result_name(result) -> str:
    for name in (
        "successful",
        "max_steps_reached",
        "nonlinear_divergence",
        "unstable_step",
        "failed",
    ):
        if bool(result == getattr(sj.RESULTS, name)):
            return name
    return "other"


def tols(rtol):
    """rtol, atol as 0-d arrays: array tolerances are traced, so no recompile."""
    return jnp.asarray(rtol, dtype=float), jnp.asarray(rtol * 1e-2, dtype=float)


def run_adaptive(rod, t1, q0, solver, rtol, max_steps=MAX_STEPS):
    rt, at = tols(rtol)
    return sj.simulate(
        rod,
        t1,
        q0,
        solver=solver,
        rtol=rt,
        atol=at,
        n_save=N_SAVE,
        max_steps=max_steps,
        throw=False,
    )


def run_fixed(rod, t1, q0, solver, h, max_steps):
    return sj.simulate(
        rod,
        t1,
        q0,
        solver=solver,
        adaptive=False,
        dt0=h,
        n_save=N_SAVE,
        max_steps=max_steps,
        throw=False,
    )


class CompileTracker:
    """Remembers which (solver, structure, controller) programs were already compiled
    in this process, and the first-call time of those compiled here."""

    def __init__(self):
        self.first_call = {}

    def warm(self, key, fn):
        """Call ``fn`` once if ``key`` is new (compiling); return its wall time."""
        if key in self.first_call:
            return None
        t0 = time.perf_counter()
        block(fn())
        self.first_call[key] = time.perf_counter() - t0
        return self.first_call[key]


TRACKER = CompileTracker()


def tip_error(tips, ref, length):
    """max over save times of |tip - tip_ref| / L (inf if not finite)."""
    d = np.linalg.norm(np.asarray(tips) - np.asarray(ref), axis=-1)
    if not np.all(np.isfinite(d)):
        return math.inf
    return float(d.max() / length)


def write_csv(path, rows):
    keys = []
    for r in rows:
        keys += [k for k in r if k not in keys]
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys)
        w.writeheader()
        w.writerows(rows)


def fmt_e(x):
    return "-" if x is None or not np.isfinite(x) else f"{x:.1e}"


# ------------------------------------------------------------------ stability theory


def stability_polynomial(solver_name):
    """|R(z)| of an explicit Runge-Kutta method (from diffrax's Butcher tableau)."""
    tab = sj.SOLVERS[solver_name]().tableau
    s = tab.num_stages
    A = np.zeros((s, s))
    for i, row in enumerate(tab.a_lower):
        A[i + 1, : len(row)] = np.asarray(row, dtype=float)
    b = np.asarray(tab.b_sol, dtype=float)

    def absR(z):
        z = np.atleast_1d(np.asarray(z, dtype=complex))
        out = np.empty(z.shape)
        for k, zk in enumerate(z):
            out[k] = abs(1 + zk * b @ np.linalg.solve(np.eye(s) - zk * A, np.ones(s)))
        return out

    return absR


def explicit_step_limit(solver_name, eigenvalues, growth=1.01):
    """Largest constant step h for which every h * lambda keeps |R| <= ``growth``.

    ``growth`` slightly above 1 ignores the tiny amplification some methods (Tsit5)
    have on the imaginary axis near the origin (1e-4 per step at h w < 1).
    """
    absR = stability_polynomial(solver_name)
    lam = np.asarray(eigenvalues, dtype=complex)
    lam = lam[np.abs(lam) > 0]
    hs = np.logspace(-3, 2, 1001) / np.abs(lam).max()
    ok = np.array([absR(h * lam).max() <= growth for h in hs])
    if ok.all():
        return float(hs[-1])
    first_bad = int(np.argmax(~ok))
    return float(hs[max(first_bad - 1, 0)])


def modal_analysis(rod, q0):
    """Natural frequencies (K v = w^2 M(q0) v) and the linearised state eigenvalues."""
    K = np.asarray(sj.stiffness_matrix(rod))
    M = np.asarray(sj.mass_matrix(rod, q0))
    D = np.asarray(sj.damping_matrix(rod))
    w2 = scipy.linalg.eigh(K, M, eigvals_only=True)
    n = K.shape[0]
    Minv = np.linalg.inv(M)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ K, -Minv @ D]])
    lam = np.linalg.eigvals(A)
    return np.sqrt(np.clip(w2, 0, None)), lam


# ------------------------------------------------------------------- part 1: WP

# Work-precision cases: (eta [Pa s], initial strain (torsion, bend y, bend z) [rad/m]).
# The free-fall rod pre-bent about y falls in the xz-plane: the out-of-plane DoFs
# (torsion, bending about z) stay exactly zero, so their stiff, strongly damped modes
# are never excited. "damped_3d" adds torsion and out-of-plane bending to the initial
# shape, which excites every mode (the case an explicit method's stability sees).
WP_CASES = {
    "undamped": (0.0, (0.0, 1.0, 0.0)),
    "damped": (ETA_DAMPED, (0.0, 1.0, 0.0)),
    "damped_3d": (ETA_DAMPED, (0.1, 1.0, 0.3)),
}
CASE_TITLE = {
    "undamped": "undamped (planar motion)",
    "damped": f"damped, eta = {ETA_DAMPED:g} Pa s (planar)",
    "damped_3d": f"damped, eta = {ETA_DAMPED:g} Pa s, 3D initial shape",
}


def initial_q(rod, strain):
    """Uniform initial strain: (torsion, bending about y, bending about z) [rad/m]."""
    tw, by, bz = strain
    return sj.strain_coordinates(rod, [tw, by, bz, 0.0, 0.0, 0.0])


def wp_settings(quick, implicit_orders):
    if quick:
        return {
            "t1": 0.5,
            "orders": (3,),
            "implicit_orders": (3,),
            "orders_3d": (3,),
            "rtols": {s: (1e-3, 1e-5, 1e-7) for s in ("tsit5", "dopri5", "kvaerno3")}
            | {"dopri8": (1e-3, 1e-6, 1e-9), "kvaerno5": (1e-3, 1e-5, 1e-7)}
            | {"implicit_euler": (1e-2, 1e-3)}
            | {"ros34pw2": (1e-2, 1e-3, 1e-4, 1e-5, 1e-6)},
            "budget_s": 2.0,
            "basis_ref_orders": (6,),
        }
    decades = tuple(10.0**-k for k in range(3, 10))
    return {
        "t1": 1.0,
        "orders": (1, 2, 3, 4),
        "implicit_orders": tuple(implicit_orders),
        "orders_3d": (3,),
        "rtols": {s: decades for s in ("tsit5", "dopri5", "kvaerno3", "kvaerno5")}
        | {"dopri8": decades + (1e-10,)}
        | {"implicit_euler": (1e-2, 1e-3, 1e-4, 1e-5)}
        | {"ros34pw2": (1e-2,) + decades[:5]},
        "budget_s": 6.0,
        "basis_ref_orders": (5, 6),
    }


REF_RTOL = 1e-12
REF_MAX_STEPS = 100_000  # the references at order 6 take more than MAX_STEPS


def case_model(case, order):
    eta, strain = WP_CASES[case]
    rod = free_fall_rod(order=order, eta=eta)
    return rod, initial_q(rod, strain)


def reference_tips(case, order, t1):
    rod, q0 = case_model(case, order)
    TRACKER.warm(
        ("dopri8", order, "pid"), partial(run_adaptive, rod, t1, q0, "dopri8", 1e-3)
    )
    t0 = time.perf_counter()
    tr = block(run_adaptive(rod, t1, q0, "dopri8", REF_RTOL, REF_MAX_STEPS))
    dt = time.perf_counter() - t0
    name = result_name(tr.result)
    if name != "successful":
        raise RuntimeError(f"reference {case} order {order} failed: {name}")
    return np.asarray(tr.tip_positions(rod)), int(tr.num_steps), dt


def case_orders(st, case, solver=None):
    if case == "damped_3d":
        return st["orders_3d"]
    if solver in IMPLICIT:
        return st["implicit_orders"]
    if solver is None:
        return tuple(sorted(set(st["orders"]) | set(st["implicit_orders"])))
    return st["orders"]


def bench_wp(quick, implicit_orders, orders=None):
    st = wp_settings(quick, implicit_orders) | {"quick": quick}
    if orders:
        st["orders"] = tuple(orders)
    t1 = st["t1"]
    refs, ref_info = {}, []
    for case in WP_CASES:
        for order in sorted(set(case_orders(st, case)) | set(st["basis_ref_orders"])):
            tips, steps, dt = reference_tips(case, order, t1)
            refs[case, order] = tips
            ref_info.append(
                {"case": case, "order": order, "steps": steps, "wall_s": round(dt, 3)}
            )
            print(
                f"    reference {case:<9} order {order}: Dopri8 rtol {REF_RTOL:g},"
                f" {steps} steps, {dt:.1f} s",
                flush=True,
            )
    top = max(st["basis_ref_orders"])
    basis_err = []
    for case, order in sorted(refs, key=lambda k: (list(WP_CASES).index(k[0]), k[1])):
        row = {"case": case, "order": order, "n_dof": 3 * (order + 1)}
        for ro in st["basis_ref_orders"]:
            if ro != order:
                row[f"err_vs_order{ro}"] = tip_error(
                    refs[case, order], refs[case, ro], L_SOFT
                )
        basis_err.append(row)

    rows = []
    for case in WP_CASES:
        for solver in run_solvers():
            for order in case_orders(st, case, solver):
                rod, q0 = case_model(case, order)
                if solver in CONSTANT:
                    rows += wp_constant(rod, q0, refs[case, order], case, solver,
                                        order, t1, st)  # fmt: skip
                    continue
                rtols = st["rtols"][solver]
                first = TRACKER.warm(
                    (solver, order, "pid"),
                    partial(run_adaptive, rod, t1, q0, solver, rtols[0]),
                )
                stop = None
                for rtol in rtols:
                    row = {
                        "case": case,
                        "solver": solver,
                        "order": order,
                        "n_dof": rod.n_dof,
                        "eta": WP_CASES[case][0],
                        "t1": t1,
                        "rtol": rtol,
                        "atol": rtol * 1e-2,
                        "first_call_s": first,
                    }
                    first = None
                    if stop is not None:
                        row["status"] = stop
                        rows.append(row)
                        continue
                    tr, med, best, n = timed(
                        partial(run_adaptive, rod, t1, q0, solver, rtol),
                        max_repeats=3,
                        budget_s=1.0,
                    )
                    name = result_name(tr.result)
                    err = (
                        tip_error(tr.tip_positions(rod), refs[case, order], L_SOFT)
                        if name == "successful"
                        else math.nan
                    )
                    row.update(
                        status=name,
                        error=err,
                        warm_median_s=med,
                        warm_min_s=best,
                        repeats=n,
                        steps=int(tr.num_steps),
                        rejected=int(tr.num_rejected_steps),
                    )
                    rows.append(row)
                    print(
                        f"    {case:<9} {solver:<14} order {order} rtol {rtol:.0e}:"
                        f" err {fmt_e(err):>7}  {med:7.3f} s  {int(tr.num_steps):6d} steps"
                        f" ({int(tr.num_rejected_steps)} rej) {'' if name == 'successful' else name}",
                        flush=True,
                    )
                    if name != "successful":
                        stop = f"skipped (looser rtol: {name})"
                    elif med > st["budget_s"]:
                        stop = f"skipped (time budget {st['budget_s']} s)"
    return {
        "settings": {
            "t1": t1,
            "n_save": N_SAVE,
            "cases": {
                k: {"eta": v[0], "initial_strain_twist_by_bz": v[1]}
                for k, v in WP_CASES.items()
            },
            "orders_explicit": st["orders"],
            "orders_implicit": st["implicit_orders"],
            "orders_3d": st["orders_3d"],
            "rtols": st["rtols"],
            "atol_over_rtol": 1e-2,
            "reference": f"dopri8 rtol {REF_RTOL:g} atol {REF_RTOL * 1e-2:g}, same order",
            "basis_reference_orders": st["basis_ref_orders"],
            "time_budget_s": st["budget_s"],
            "max_steps": MAX_STEPS,
            "timing": "first call per (solver, order) compiles; then median of up to 3 calls (1 s budget)",
        },
        "references": ref_info,
        "basis_error": basis_err,
        "basis_top_order": top,
        "rows": rows,
    }


def wp_constant(rod, q0, ref, case, solver, order, t1, st):
    """Work-precision rows of a constant-step solver: one per step of ``WP_DTS``."""
    rows, first, stop = [], None, None
    dts = WP_DTS[::2] if st.get("quick") else WP_DTS
    for h in dts:
        n = int(math.ceil(t1 / h - 1e-9))
        fn = partial(run_fixed, rod, t1, q0, solver, h, max(n, MAX_STEPS))
        first = TRACKER.warm((solver, order, "const", MAX_STEPS), fn)
        row = {
            "case": case, "solver": solver, "order": order, "n_dof": rod.n_dof,
            "eta": WP_CASES[case][0], "t1": t1, "rtol": None, "atol": None, "dt": h,
            "first_call_s": first,
        }  # fmt: skip
        if stop is not None:
            rows.append(row | {"status": stop})
            continue
        tr, med, best, nrep = timed(fn, max_repeats=3, budget_s=1.0)
        name = result_name(tr.result)
        err = (
            tip_error(tr.tip_positions(rod), ref, L_SOFT)
            if name == "successful"
            else math.nan
        )
        rows.append(row | dict(status=name, error=err, warm_median_s=med,
                               warm_min_s=best, repeats=nrep,
                               steps=int(tr.num_steps), rejected=0))  # fmt: skip
        print(
            f"    {case:<9} {solver:<14} order {order} dt {h:.0e}:"
            f" err {fmt_e(err):>7}  {med:7.3f} s  {int(tr.num_steps):6d} steps"
            f" {'' if name == 'successful' else name}",
            flush=True,
        )
        if med > st["budget_s"]:
            stop = f"skipped (time budget {st['budget_s']} s)"
    return rows


def wp_best(rows, case, order, level):
    """Per solver: the fastest run with error <= level (case and order fixed)."""
    best = {}
    for r in rows:
        if (
            r.get("status") != "successful"
            or r.get("case") != case
            or r["order"] != order
        ):
            continue
        if r["error"] <= level and (
            r["solver"] not in best
            or r["warm_median_s"] < best[r["solver"]]["warm_median_s"]
        ):
            best[r["solver"]] = r
    return best


def plot_wp(res, path_wp, path_order):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = res["rows"]
    cases = list(res["settings"]["cases"])
    top = res["basis_top_order"]
    fig, axes = plt.subplots(
        1, len(cases), figsize=(6 * len(cases), 5.5), sharey=True, sharex=True
    )
    for ax, case in zip(axes, cases, strict=True):
        for solver in SOLVERS:
            col, mk = STYLE[solver]
            orders = sorted(
                {
                    r["order"]
                    for r in rows
                    if r["solver"] == solver and r["case"] == case
                }
            )
            for order in orders:
                pts = [
                    r
                    for r in rows
                    if r["solver"] == solver
                    and r["case"] == case
                    and r["order"] == order
                    and "warm_median_s" in r
                ]
                ok = [r for r in pts if r["status"] == "successful"]
                main = order == 3
                ax.plot(
                    [r["warm_median_s"] for r in ok],
                    [max(r["error"], 1e-16) for r in ok],
                    marker=mk,
                    color=col,
                    lw=1.6 if main else 0.8,
                    ls="-" if main else ":",
                    ms=6 if main else 3.5,
                    alpha=1.0 if main else 0.6,
                    label=solver if main or 3 not in orders else None,
                )
                for r in pts:
                    if r["status"] != "successful":
                        ax.plot(r["warm_median_s"], 1.0, marker="x", color=col, ms=9)
        for b in res["basis_error"]:
            if b["order"] == 3 and b["case"] == case:
                e = b.get(f"err_vs_order{top}")
                ax.axhline(e, color="k", ls="--", lw=0.8)
                ax.text(
                    0.01,
                    e * 1.3,
                    f"basis error, order 3 vs {top}",
                    fontsize=8,
                    transform=ax.get_yaxis_transform(),
                )
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.grid(True, which="both", alpha=0.3)
        ax.set_xlabel("warm wall time [s]")
        ax.set_title(
            f"free-fall rod, {res['settings']['t1']:g} s: {CASE_TITLE[case]}",
            fontsize=10,
        )
    axes[0].set_ylabel("max_t |tip - tip_ref| / L")
    axes[0].legend(
        title="order 3 solid; 1, 2, 4 dotted; x = failed",
        fontsize=8,
        title_fontsize=8,
    )
    fig.tight_layout()
    fig.savefig(path_wp, dpi=110)
    plt.close(fig)

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(12, 4.8))
    be = res["basis_error"]
    for case, ls in zip(cases, ("o-", "s--", "^:"), strict=True):
        pts = [b for b in be if b["case"] == case and f"err_vs_order{top}" in b]
        ax1.semilogy(
            [b["order"] for b in pts],
            [b[f"err_vs_order{top}"] for b in pts],
            "k" + ls,
            label=CASE_TITLE[case],
        )
    ax1.set_xlabel("Legendre order (n_dof = 3 (order + 1))")
    ax1.set_ylabel(f"max_t |tip_ref(order) - tip_ref(order {top})| / L")
    ax1.set_title(
        "basis (discretisation) error of the reference solutions", fontsize=10
    )
    ax1.grid(True, which="both", alpha=0.3)
    ax1.legend(fontsize=8)
    level = 1e-4
    for solver in SOLVERS:
        col, mk = STYLE[solver]
        for case, ls in zip(cases[:2], ("-", "--"), strict=True):
            xs, ys = [], []
            for order in sorted({r["order"] for r in rows}):
                b = wp_best(rows, case, order, level).get(solver)
                if b is not None:
                    xs.append(order)
                    ys.append(b["warm_median_s"])
            if xs:
                ax2.semilogy(
                    xs, ys, marker=mk, color=col, ls=ls, label=f"{solver}, {case}"
                )
    ax2.set_xlabel("Legendre order")
    ax2.set_ylabel(f"fastest warm time to error <= {level:g} [s]")
    ax2.set_title(
        "cost of a 1e-4 tip trajectory (vs same-order reference)", fontsize=10
    )
    ax2.grid(True, which="both", alpha=0.3)
    ax2.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    fig.savefig(path_order, dpi=110)
    plt.close(fig)


def print_wp(res):
    rows = res["rows"]
    top = res["basis_top_order"]
    print(f"\n    basis error (reference at order k vs order {top})")
    for b in res["basis_error"]:
        if f"err_vs_order{top}" in b:
            print(
                f"      {b['case']:<9} order {b['order']} ({b['n_dof']} DoF):"
                f" {b[f'err_vs_order{top}']:.2e}"
            )
    for case in res["settings"]["cases"]:
        for level in (1e-3, 1e-4, 1e-6):
            best = wp_best(rows, case, 3, level)
            line = ", ".join(
                f"{s} {b['warm_median_s'] * 1e3:.0f} ms ("
                + (f"dt {b['dt']:.0e}" if b.get("dt") else f"rtol {b['rtol']:.0e}")
                + ")"
                for s, b in sorted(best.items(), key=lambda kv: kv[1]["warm_median_s"])
            )
            print(f"    {case}, order 3, error <= {level:g}: {line or '-'}")


# ------------------------------------------------------------ part 2: stability


def stiff_rod():
    """Steel rod: L 0.2 m, r 1 mm, E 200 GPa, nu 0.3, rho 7800, same modes/order.

    The radius is given as a (constant) taper so that the model has the same pytree
    structure as the free-fall rod and shares its compiled programs.
    """
    div = sj.Division(
        0.2, sj.CircularSection((0.001, 0.001)), sj.LegendreBasis(MODES, 3)
    )
    rod = sj.SoftLink([div], sj.Material(E=2e11, poisson=0.3, rho=7800.0, eta=0.0))
    return sj.Linkage([rod], gravity=(0.0, 0.0, -9.81))


FLOOR_STIFFNESS = 1e7  # contact stiffness of the rod on a floor [N/m^2]
FLOOR_DEPTH = 0.03  # the floor below the clamp [m]
FLOOR_START = (0.1, 0.0, 0.3)  # its initial strain: level, bent sideways, twisted


def rod_on_floor():
    """The soft free-fall rod falling onto a stiff floor 3 cm below its clamp.

    It starts level (:data:`FLOOR_START`: bent sideways and twisted, every mode
    excited) with its surface clear of the floor, sags and strikes it.

    Penalty contact ``k = 1e7 N/m^2`` (smoothing 1e-6 m, no damping): the contact's
    own frequency ``sqrt(k / (rho A))`` (5.6e3 to 1.1e4 rad/s along the tapered rod)
    is above the rod's fastest elastic mode, so an explicit solver's step is bounded
    by the contact.
    """
    rod = free_fall_rod(order=3)
    law = sj.ContactLaw(stiffness=FLOOR_STIFFNESS, smoothing=1e-6)
    floor = sj.Plane(point=(0.0, 0.0, -FLOOR_DEPTH))
    return sj.Linkage(rod.links, gravity=(0.0, 0.0, -9.81),
                      contact=sj.Contact(floor, law, spacing=0.01))  # fmt: skip


def floor_frequency() -> float:
    """The contact's highest frequency ``sqrt(k / (rho A))`` at the rod's thin tip."""
    return math.sqrt(FLOOR_STIFFNESS / (1000.0 * math.pi * 0.01**2))


def start_strain(rod):
    """The stability runs' initial strain: :data:`FLOOR_START` over the floor."""
    return STAB_STRAIN if rod.contact is None else FLOOR_START


def classify(tr, rod, length):
    name = result_name(tr.result)
    if name in ("nonlinear_divergence", "unstable_step"):
        return "diverged", name
    if name == "max_steps_reached":
        return "max steps", name
    if name != "successful":
        return "failed", name
    q = np.asarray(tr.q)
    if not np.all(np.isfinite(q)):
        return "diverged", name
    tips = np.asarray(tr.tip_positions(rod))
    if (
        not np.all(np.isfinite(tips))
        or np.linalg.norm(tips, axis=-1).max() > 2 * length
    ):
        return "diverged", name
    if rod.contact is not None and energy_gain(tr, rod) > ENERGY_GAIN:
        return "energy gain", name
    return "ok", name


ENERGY_GAIN = 0.1
"""A run over the floor (no damping) is ``energy gain`` when its total energy (the
contact's potential included) rises above the start by more than this share of its
largest kinetic energy: the integration, not the physics, put the energy in."""


@eqx.filter_jit
def _energies(rod, q, qd):
    def one(q_, qd_):
        kinetic = 0.5 * qd_ @ sj.mass_matrix(rod, q_) @ qd_
        return sj.total_energy(rod, q_, qd_), kinetic

    return jax.vmap(one)(q, qd)


def energy_gain(tr, rod) -> float:
    """Largest rise of the total energy over the start, per largest kinetic energy."""
    e, k = (np.asarray(a) for a in _energies(rod, tr.q, tr.qd))
    return float(np.max(e - e[0]) / max(np.max(k), 1e-300))


STEPS = (1e-2, 1e-3, 1e-4, 1e-5)
STAB_STRAIN = (0.1, 1.0, 0.3)  # 3D initial shape: every mode excited
ADAPT_RTOLS = (1e-3, 1e-6)


def bench_stability(quick):
    n_fixed = 200 if quick else 1000
    max_fixed = n_fixed + 16
    rods = {
        "soft": (free_fall_rod(order=3), L_SOFT, 0.2),
        "soft_damped": (free_fall_rod(order=3, eta=ETA_DAMPED), L_SOFT, 0.2),
        "stiff": (stiff_rod(), 0.2, 0.02),
        "soft_on_floor": (rod_on_floor(), L_SOFT, 0.2),
    }
    theory = {}
    for name, (rod, _, _) in rods.items():
        q0 = initial_q(rod, start_strain(rod))
        w, lam = modal_analysis(rod, q0)
        if rod.contact is not None:  # the floor's stiffness: an undamped frequency
            wc = floor_frequency()
            w, lam = np.append(w, wc), np.append(lam, [1j * wc, -1j * wc])
        limits = {s: explicit_step_limit(s, lam) for s in EXPLICIT}
        theory[name] = {
            "w_min_rad_s": float(w.min()),
            "w_max_rad_s": float(w.max()),
            "f_max_hz": float(w.max() / (2 * math.pi)),
            "max_abs_eigenvalue": float(np.abs(lam).max()),
            "explicit_h_limit_s": limits,
        }
        print(
            f"    {name} rod: natural frequencies {w.min():.3g} .. {w.max():.4g} rad/s"
            f" (f_max {w.max() / (2 * math.pi):.4g} Hz); explicit step limits "
            + ", ".join(f"{s} {h:.2e} s" for s, h in limits.items()),
            flush=True,
        )
    # Damped soft rod (eta 1e4), for reference in the WP discussion.
    rod_d = free_fall_rod(order=3, eta=ETA_DAMPED)
    _, lam_d = modal_analysis(rod_d, initial_q(rod_d, STAB_STRAIN))
    theory["soft_damped_eta1e4"] = {
        "max_abs_eigenvalue": float(np.abs(lam_d).max()),
        "explicit_h_limit_s": {s: explicit_step_limit(s, lam_d) for s in EXPLICIT},
    }
    print(
        f"    soft rod damped (eta {ETA_DAMPED:g}): max |lambda| {np.abs(lam_d).max():.4g} 1/s;"
        " explicit step limits "
        + ", ".join(
            f"{s} {h:.2e} s"
            for s, h in theory["soft_damped_eta1e4"]["explicit_h_limit_s"].items()
        ),
        flush=True,
    )

    rows = []
    for solver in run_solvers():
        # Compile both controllers once (the rods without contact share the
        # programs; the rod over the floor has its own), outside the timed cells.
        for key, warm_rod in (
            ("", rods["soft"][0]),
            ("floor", rods["soft_on_floor"][0]),
        ):
            q0 = initial_q(warm_rod, start_strain(warm_rod))
            TRACKER.warm(
                (solver, 3, "const", max_fixed, key),
                partial(run_fixed, warm_rod, 2e-3, q0, solver, 1e-3, max_fixed),
            )
            if solver not in CONSTANT:
                TRACKER.warm(
                    (solver, 3, "pid", STAB_MAX_STEPS, key),
                    partial(
                        run_adaptive, warm_rod, 1e-3, q0, solver, 1e-3, STAB_MAX_STEPS
                    ),
                )
            if warm_rod.contact is not None:
                energy_gain(run_fixed(warm_rod, 2e-3, q0, solver, 1e-3, max_fixed),
                            warm_rod)  # fmt: skip
        for rname, (rod, length, T) in rods.items():
            q0 = initial_q(rod, start_strain(rod))
            cells = [("h", h) for h in STEPS]
            if solver not in CONSTANT:  # constant-step solvers: no adaptive cells
                cells += [("rtol", r) for r in ADAPT_RTOLS]
            for kind, val in cells:
                if kind == "h":
                    span = min(T, n_fixed * val)
                    fn = partial(run_fixed, rod, span, q0, solver, val, max_fixed)
                else:
                    span = T
                    fn = partial(
                        run_adaptive, rod, span, q0, solver, val, STAB_MAX_STEPS
                    )

                t0 = time.perf_counter()
                tr = block(fn())
                wall = time.perf_counter() - t0
                outcome, code = classify(tr, rod, length)
                row = {
                    "rod": rname,
                    "solver": solver,
                    "mode": "constant" if kind == "h" else "adaptive",
                    "h": val if kind == "h" else None,
                    "rtol": val if kind == "rtol" else None,
                    "span_s": span,
                    "outcome": outcome,
                    "result": code,
                    "steps": int(tr.num_steps),
                    "rejected": int(tr.num_rejected_steps),
                    "wall_s": wall,
                }
                rows.append(row)
                print(
                    f"    {rname:<5} {solver:<15} {kind} {val:.0e} span {span:.3g} s:"
                    f" {outcome:<9} {int(tr.num_steps):6d} steps {wall:7.2f} s",
                    flush=True,
                )
    return {
        "settings": {
            "rods": {
                "soft": "free_fall_rod(order=3): L 0.5 m, r 2->1 cm, E 1 MPa, rho 1000, eta 0",
                "soft_damped": f"the soft rod with eta {ETA_DAMPED:g} Pa s (its fastest modes are damped)",
                "stiff": "steel: L 0.2 m, r 1 mm, E 200 GPa, nu 0.3, rho 7800, eta 0, order 3",
                "soft_on_floor": f"the soft rod over a floor {FLOOR_DEPTH} m below its clamp, penalty k {FLOOR_STIFFNESS:g} N/m^2, smoothing 1e-6 m, no damping",
            },
            "q0": "uniform strain: torsion 0.1, bending 1 (about y) and 0.3 (about z) rad/m, at rest; gravity -z (3D: excites every mode)",
            "spans_s": {k: v[2] for k, v in rods.items()},
            "constant_steps": STEPS,
            "constant_step_runs_cover": f"min(span, {n_fixed} h)",
            "constant_step_max_steps": max_fixed,
            "adaptive_rtols": ADAPT_RTOLS,
            "adaptive_max_steps": STAB_MAX_STEPS,
            "diverged_if": "non-finite state, result nonlinear_divergence, or |tip| > 2 L",
            "explicit_limit_definition": "largest h with |R(h lambda)| <= 1.01 for all eigenvalues of the linearisation at q0 (no gravity)",
        },
        "theory": theory,
        "rows": rows,
    }


OUTCOME_COLOUR = {
    "ok": "#4caf50",
    "diverged": "#e53935",
    "max steps": "#fb8c00",
    "failed": "#8e24aa",
    "energy gain": "#fdd835",
    "not run": "#bdbdbd",
}


def plot_stability(res, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch

    rows = res["rows"]
    cols = [f"h={h:.0e}" for h in STEPS] + [f"rtol={r:.0e}" for r in ADAPT_RTOLS]
    names = [
        n
        for n in ("soft", "soft_damped", "stiff", "soft_on_floor")
        if n in res["theory"]
    ]
    ncol = min(len(names), 2)
    nrow = -(-len(names) // ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(7 * ncol, 4.3 * nrow))
    axes = np.atleast_1d(axes).ravel()
    for ax in axes[len(names) :]:
        ax.set_visible(False)
    axes = axes[: len(names)]
    for ax, rname in zip(axes, names, strict=True):
        for i, solver in enumerate(SOLVERS):
            for j, c in enumerate(cols):
                match = [
                    r
                    for r in rows
                    if r["rod"] == rname
                    and r["solver"] == solver
                    and (
                        (r["h"] is not None and c == f"h={r['h']:.0e}")
                        or (r["rtol"] is not None and c == f"rtol={r['rtol']:.0e}")
                    )
                ]
                r = match[0] if match else None
                outcome = r["outcome"] if r else "not run"
                ax.add_patch(
                    plt.Rectangle(
                        (j, i), 1, 1, color=OUTCOME_COLOUR[outcome], ec="white"
                    )
                )
                if r:
                    ax.text(
                        j + 0.5,
                        i + 0.5,
                        f"{r['wall_s']:.2f} s\n{r['steps']} st",
                        ha="center",
                        va="center",
                        fontsize=7,
                    )
        ax.set_xlim(0, len(cols))
        ax.set_ylim(len(SOLVERS), 0)
        ax.set_xticks(np.arange(len(cols)) + 0.5, cols, fontsize=8)
        ax.set_yticks(np.arange(len(SOLVERS)) + 0.5, SOLVERS, fontsize=8)
        th = res["theory"][rname]
        ax.set_title(
            f"{rname} rod (w_max {th['w_max_rad_s']:.3g} rad/s, max |lambda|"
            f" {th.get('max_abs_eigenvalue', th['w_max_rad_s']):.3g} 1/s; tsit5 limit"
            f" {th['explicit_h_limit_s']['tsit5']:.1e} s)",
            fontsize=9,
        )
    fig.legend(
        handles=[Patch(color=v, label=k) for k, v in OUTCOME_COLOUR.items()],
        loc="lower center",
        ncol=6,
    )
    fig.tight_layout(rect=(0, 0.07, 1, 1))
    fig.savefig(path, dpi=120)
    plt.close(fig)


# ---------------------------------------------------------------- part 3: speed


def speed_choices(wp_rows, level=1e-4, slack=1.5):
    """Default solver + the two fastest solvers at error <= ~level (damped, order 3)."""
    best = wp_best(wp_rows, "damped", 3, level * slack) if wp_rows else {}
    ranked = sorted(
        (r for r in best.values() if r["solver"] not in CONSTANT),
        key=lambda r: r["warm_median_s"],
    )
    chosen = [(r["solver"], r["rtol"], "WP best") for r in ranked[:2]]
    default = sj.integrate.DEFAULT_SOLVER
    if default in best:
        if default not in [c[0] for c in chosen]:
            chosen.append((default, best[default]["rtol"], "default, WP rtol"))
    chosen.append((default, DEFAULT_RTOL, "default solver, default tolerances"))
    if len(ranked) < 2:
        chosen += [("dopri8", 1e-6, "fallback"), ("tsit5", 1e-5, "fallback")]
    return chosen


def bench_speed(quick, wp_rows):
    t1 = 5.0
    rod = free_fall_rod(order=3, eta=ETA_DAMPED)
    q0 = free_fall_q0(rod)
    choices = speed_choices(wp_rows)
    repeats = 5
    # Reference for the 5 s run's error.
    TRACKER.warm(
        ("dopri8", 3, "pid"), lambda: run_adaptive(rod, 1e-3, q0, "dopri8", 1e-3).q
    )
    ref = block(run_adaptive(rod, t1, q0, "dopri8", 1e-11))
    ref_tips = np.asarray(ref.tip_positions(rod))
    print(
        f"    reference: dopri8 rtol 1e-11, {int(ref.num_steps)} steps,"
        f" {result_name(ref.result)}",
        flush=True,
    )
    rows = []
    for solver, rtol, why in choices:
        if solver == "auto":  # resolve on the host (the AOT trace below has no values)
            solver = sj.integrate.auto_solver(rod, q0, 0.0, t1, rtol)
            why = f"{why}: auto -> {solver}"

        def run(rod, q0, rt, at, solver=solver):
            tr = sj.simulate(
                rod,
                t1,
                q0,
                solver=solver,
                rtol=rt,
                atol=at,
                n_save=N_SAVE,
                max_steps=MAX_STEPS,
                throw=False,
            )
            return tr

        rt, at = tols(rtol)
        if why.startswith("default solver"):
            at = jnp.asarray(DEFAULT_ATOL)  # simulate's own defaults
        t0 = time.perf_counter()
        compiled = eqx.filter_jit(run).lower(rod, q0, rt, at).compile()
        tc = time.perf_counter() - t0
        tr, med, best, n = timed(
            partial(compiled, rod, q0, rt, at),
            min_repeats=repeats,
            max_repeats=repeats,
            budget_s=0,
        )
        # The public call path (filter_jit dispatch); compiled already if part 1 ran
        # in this process with the same solver (array tolerances: no recompile).
        first_pub = TRACKER.warm(
            (solver, 3, "pid"), partial(run_adaptive, rod, t1, q0, solver, rtol)
        )
        _, med_pub, _, _ = timed(
            partial(run, rod, q0, rt, at),  # not compiled ahead: simulate's dispatch
            min_repeats=repeats,
            max_repeats=repeats,
            budget_s=0,
        )
        name = result_name(tr.result)
        err = tip_error(tr.tip_positions(rod), ref_tips, L_SOFT)
        row = {
            "solver": solver,
            "why": why,
            "rtol": float(rt),
            "atol": float(at),
            "t1": t1,
            "status": name,
            "error": err,
            "steps": int(tr.num_steps),
            "rejected": int(tr.num_rejected_steps),
            "compile_s": tc,
            "warm_median_s": med,
            "warm_min_s": best,
            "repeats": n,
            "public_first_call_s": first_pub,
            "public_warm_median_s": med_pub,
            "sorosim_ratio": SOROSIM_5S_S / med,
            "target_met": med < SPEED_TARGET_S,
        }
        rows.append(row)
        print(
            f"    {solver:<15} rtol {float(rt):.0e} ({why}): compile {tc:6.1f} s,"
            f" warm {med * 1e3:8.1f} ms (public {med_pub * 1e3:8.1f} ms),"
            f" {row['steps']} steps, err {fmt_e(err)},"
            f" SoRoSim/ours {row['sorosim_ratio']:.2f}x,"
            f" target {'met' if row['target_met'] else 'NOT met'}",
            flush=True,
        )
    return {
        "settings": {
            "rod": "free_fall_rod(order=3, eta=1e4): 12 DoF",
            "t1": t1,
            "n_save": N_SAVE,
            "max_steps": MAX_STEPS,
            "repeats": repeats,
            "sorosim_s": SOROSIM_5S_S,
            "target_s": SPEED_TARGET_S,
            "error_reference": "dopri8 rtol 1e-11",
            "compile": "eqx.filter_jit(run).lower(...).compile() (AOT, trace + lower + XLA)",
        },
        "reference_steps": int(ref.num_steps),
        "rows": rows,
    }


# -------------------------------------------------------------- part 4: scaling


def bench_scaling(quick):
    # (a) n_dof: two series: Tsit5 adaptive rtol 1e-6 on the undamped free-fall rod,
    # and the default for damped rods (ROS34PW2, rtol 1e-3) on the damped one.
    t1 = 0.2 if quick else 0.5
    series = (("tsit5", 0.0, 1e-6), ("ros34pw2", ETA_DAMPED, 1e-3))
    if quick:
        configs = [(MODES, 1), (MODES, 3), (MODES, 9), ((1,) * 6, 0), ((1,) * 6, 4)]
    else:
        configs = [(MODES, o) for o in (1, 3, 5, 9, 14, 19)] + [
            ((1,) * 6, o) for o in (0, 1, 3, 4, 9)
        ]
    ndof_rows = []
    for (solver, eta, rtol), (modes, order) in (
        (a, b) for a in series for b in configs
    ):
        rod = free_fall_rod(order=order, modes=modes, eta=eta)
        q0 = free_fall_q0(rod)
        first = TRACKER.warm(
            (solver, order, "pid", modes),
            partial(run_adaptive, rod, 1e-3, q0, solver, rtol),
        )
        tr, med, best, n = timed(
            partial(run_adaptive, rod, t1, q0, solver, rtol),
            max_repeats=5,
            budget_s=3.0,
        )
        name = result_name(tr.result)
        steps = int(tr.num_steps)
        row = {
            "modes": "".join(map(str, modes)),
            "order": order,
            "n_dof": rod.n_dof,
            "solver": solver,
            "eta": eta,
            "rtol": rtol,
            "t1": t1,
            "status": name,
            "steps": steps,
            "first_call_s": first,
            "warm_median_s": med,
            "repeats": n,
            "wall_per_sim_second_s": med / t1,
            "wall_per_step_ms": 1e3 * med / max(steps, 1),
        }
        ndof_rows.append(row)
        print(
            f"    {solver:<9} eta {eta:g} modes {row['modes']} order {order:2d}"
            f" ({rod.n_dof:2d} DoF):"
            f" {med:7.3f} s for {t1} s ({row['wall_per_sim_second_s']:.3f} s per"
            f" simulated s), {steps} steps, {row['wall_per_step_ms']:.3f} ms/step,"
            f" compile+run {first:.1f} s {name}",
            flush=True,
        )

    # (b) vmap over E: tsit5, constant step 1e-3, 0.2 s (200 steps), order 3.
    h, tb = 1e-3, 0.2
    n_steps = int(round(tb / h))
    max_b = n_steps + 16
    base = free_fall_rod(order=3)
    q0 = free_fall_q0(base)

    def one(E):
        rod = free_fall_rod(order=3, E=E)
        tr = run_fixed(rod, tb, q0, "tsit5", h, max_b)
        return tr.q[-1], tr.result._value

    single = jax.jit(one)
    n_loop = 8 if quick else 16
    Es_loop = jnp.linspace(0.5e6, 2e6, n_loop)
    t0 = time.perf_counter()
    block(single(Es_loop[0]))
    tc_single = time.perf_counter() - t0

    def loop():
        return [single(E)[0] for E in Es_loop]

    _, med_loop, _, _ = timed(loop, min_repeats=3, max_repeats=3, budget_s=0)
    per_loop = med_loop / n_loop
    batch_rows = [
        {
            "method": "loop",
            "batch": 1,
            "compile_s": tc_single,
            "warm_median_s": med_loop,
            "per_sim_s": per_loop,
            "speedup_vs_loop": 1.0,
            "n_failed": 0,
        }
    ]
    print(
        f"    one at a time: {per_loop * 1e3:.1f} ms per simulation"
        f" ({n_loop} timed, compile+run {tc_single:.1f} s)",
        flush=True,
    )
    sizes = (1, 4, 16, 64) if quick else (1, 4, 16, 64, 256, 1024)
    batched = jax.jit(jax.vmap(one))
    for b in sizes:
        Es = jnp.linspace(0.5e6, 2e6, b)
        t0 = time.perf_counter()
        compiled = batched.lower(Es).compile()
        tc = time.perf_counter() - t0
        (qf, codes), med, best, n = timed(
            partial(compiled, Es), min_repeats=1, max_repeats=5, budget_s=4.0
        )
        n_failed = int(np.sum(np.asarray(codes) != 0)) + int(
            np.sum(~np.all(np.isfinite(np.asarray(qf)), axis=-1))
        )
        row = {
            "method": "vmap",
            "batch": b,
            "compile_s": tc,
            "warm_median_s": med,
            "repeats": n,
            "per_sim_s": med / b,
            "speedup_vs_loop": per_loop / (med / b),
            "n_failed": n_failed,
        }
        batch_rows.append(row)
        print(
            f"    vmap batch {b:5d}: {med:8.3f} s, {1e3 * med / b:7.2f} ms per simulation,"
            f" {row['speedup_vs_loop']:.2f}x vs loop, compile {tc:.1f} s, failed {n_failed}",
            flush=True,
        )
    return {
        "settings": {
            "ndof": {
                "series": [
                    {"solver": sv, "eta": e, "rtol": rt, "atol": rt * 1e-2}
                    for sv, e, rt in series
                ],
                "t1": t1,
                "rod": "free_fall_rod(order, modes, eta)",
            },
            "batch": {
                "solver": "tsit5",
                "constant_step_s": h,
                "t1": tb,
                "steps": n_steps,
                "vmap_over": "E in linspace(0.5e6, 2e6, batch), order 3, eta 0",
                "loop": f"{n_loop} jitted single simulations, per-simulation mean",
            },
        },
        "ndof_rows": ndof_rows,
        "batch_rows": batch_rows,
    }


def plot_scaling(res, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(12, 4.8))
    rows = res["ndof_rows"]
    for solver, col in (("tsit5", "tab:blue"), ("ros34pw2", "black")):
        for modes, mk in (("111000", "o"), ("111111", "s")):
            pts = sorted(
                (
                    r
                    for r in rows
                    if r["modes"] == modes and r.get("solver", "tsit5") == solver
                ),
                key=lambda r: r["n_dof"],
            )
            if not pts:
                continue
            nd = [r["n_dof"] for r in pts]
            lab = f"{solver} (eta {pts[0].get('eta', 0.0):g}), modes {modes}"
            ax1.loglog(
                nd,
                [r["wall_per_sim_second_s"] for r in pts],
                mk + "-",
                color=col,
                label=f"{lab}: per simulated s",
            )
            ax1.loglog(
                nd,
                [r["wall_per_step_ms"] * 1e-3 for r in pts],
                mk + ":",
                color=col,
                alpha=0.5,
                label=f"{lab}: per step",
            )
    ax1.set_xlabel("n_dof")
    ax1.set_ylabel("wall time [s]")
    ax1.set_title(
        "free-fall rod: "
        + "; ".join(
            f"{x['solver']} rtol {x['rtol']:g}, eta {x['eta']:g}"
            for x in res["settings"]["ndof"].get("series", [])
        ),
        fontsize=9,
    )
    ax1.grid(True, which="both", alpha=0.3)
    ax1.legend(fontsize=8)
    br = [r for r in res["batch_rows"] if r["method"] == "vmap"]
    loop = [r for r in res["batch_rows"] if r["method"] == "loop"][0]
    ax2.loglog(
        [r["batch"] for r in br], [r["per_sim_s"] for r in br], "o-", label="vmap"
    )
    ax2.axhline(loop["per_sim_s"], color="k", ls="--", label="one at a time (loop)")
    ax2.set_xlabel("batch size")
    ax2.set_ylabel("wall time per simulation [s]")
    ax2.set_title("vmap over E: tsit5, h = 1e-3, 0.2 s (200 steps), 12 DoF", fontsize=9)
    ax2.grid(True, which="both", alpha=0.3)
    ax2.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


# ------------------------------------------------------------------------ main


def load_json(path):
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return {}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer points, shorter spans")
    ap.add_argument(
        "--part",
        choices=("wp", "stability", "speed", "scaling"),
        action="append",
        help="run only this part (repeatable); default all",
    )
    ap.add_argument(
        "--implicit-orders",
        type=int,
        nargs="+",
        default=[3],
        help="basis orders at which the implicit solvers enter the WP sweep"
        " (default 3: each costs 0.5-2 min of compilation)",
    )
    ap.add_argument(
        "--orders",
        type=int,
        nargs="+",
        default=None,
        help="basis orders of the explicit solvers in the WP sweep (default: 3 with"
        " --quick, 1 2 3 4 without)",
    )
    ap.add_argument(
        "--solvers",
        nargs="+",
        choices=SOLVERS,
        default=None,
        help="measure only these solvers in the wp and stability parts; the other "
        "solvers' rows are kept from the previous results (their environment is "
        "that run's)",
    )
    args = ap.parse_args(argv)
    global ONLY
    ONLY = tuple(args.solvers) if args.solvers else None
    parts = args.part or ["wp", "stability", "speed", "scaling"]
    RESULTS_DIR.mkdir(parents=True, exist_ok=True)
    jpath = RESULTS_DIR / "dynamics.json"
    out = load_json(jpath)
    env = environment()
    print(
        f"jax {env['jax_version']} on {env['devices']}, {env['cpu_count']} CPUs,"
        f" load average {env['load_average_at_start'][0]:.1f},"
        f" default solver {env['default_solver']}",
        flush=True,
    )
    t_all = time.perf_counter()

    def record(key, res, t_part):
        res["environment"] = env | {"load_average_at_end": list(os.getloadavg())}
        res["quick"] = args.quick
        res["part_wall_s"] = t_part
        out[key] = res
        jpath.write_text(json.dumps(out, indent=2, default=str))

    wp_rows = None
    if "wp" in parts:
        print("\n[1] Work-precision, free-fall rod", flush=True)
        t0 = time.perf_counter()
        res = bench_wp(args.quick, args.implicit_orders, args.orders)
        res["rows"] = merged_rows(res["rows"], out.get("wp"))
        res["solvers_measured"] = run_solvers()
        write_csv(RESULTS_DIR / "dynamics_wp.csv", res["rows"])
        write_csv(RESULTS_DIR / "dynamics_wp_basis.csv", res["basis_error"])
        plot_wp(
            res, RESULTS_DIR / "dynamics_wp.png", RESULTS_DIR / "dynamics_wp_order.png"
        )
        print_wp(res)
        record("wp", res, time.perf_counter() - t0)
        wp_rows = res["rows"]
        print(f"    part time {time.perf_counter() - t0:.0f} s", flush=True)
    if "stability" in parts:
        print("\n[2] Stability: soft and steel rods", flush=True)
        t0 = time.perf_counter()
        res = bench_stability(args.quick)
        res["rows"] = merged_rows(res["rows"], out.get("stability"))
        res["solvers_measured"] = run_solvers()
        write_csv(RESULTS_DIR / "dynamics_stability.csv", res["rows"])
        plot_stability(res, RESULTS_DIR / "dynamics_stability.png")
        record("stability", res, time.perf_counter() - t0)
        print(f"    part time {time.perf_counter() - t0:.0f} s", flush=True)
    if "speed" in parts:
        print("\n[3] Speed: 5 s of the damped free-fall rod", flush=True)
        t0 = time.perf_counter()
        if wp_rows is None:
            wp_rows = out.get("wp", {}).get("rows")
            if wp_rows:
                print("    (solver choice from the saved work-precision results)")
        res = bench_speed(args.quick, wp_rows)
        write_csv(RESULTS_DIR / "dynamics_speed.csv", res["rows"])
        record("speed", res, time.perf_counter() - t0)
        print(f"    part time {time.perf_counter() - t0:.0f} s", flush=True)
    if "scaling" in parts:
        print("\n[4] Scaling: n_dof and vmap batch", flush=True)
        t0 = time.perf_counter()
        res = bench_scaling(args.quick)
        write_csv(RESULTS_DIR / "dynamics_scaling_ndof.csv", res["ndof_rows"])
        write_csv(RESULTS_DIR / "dynamics_scaling_batch.csv", res["batch_rows"])
        plot_scaling(res, RESULTS_DIR / "dynamics_scaling.png")
        record("scaling", res, time.perf_counter() - t0)
        print(f"    part time {time.perf_counter() - t0:.0f} s", flush=True)
    print(
        f"\nTotal {time.perf_counter() - t_all:.0f} s; load average at end"
        f" {os.getloadavg()[0]:.1f}. Wrote {jpath} and dynamics_*.csv/png",
        flush=True,
    )


if __name__ == "__main__":
    main()
