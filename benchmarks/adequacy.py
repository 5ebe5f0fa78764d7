"""Model adequacy benchmark: ``choose_model`` against uniform orders on statics scenes.

Run from the repository root::

    .venv/bin/python benchmarks/adequacy.py             # 14 scenes, uniform orders to 16
    .venv/bin/python benchmarks/adequacy.py --quick     # 6 scenes, orders to 10, 3 repeats
    .venv/bin/python benchmarks/adequacy.py --scenes planar_tip_force l_beam

For every scene (tip loads, gravity, cables, closed loops, a rigid + soft chain, a rod
clamped at both ends buckled to 0.8 L and one whose far end is clamped at a twisted
out-of-plane pose; every soft division has a Legendre basis) and every tolerance in ``TOLS`` (relative to the
reference length, the longest link):

- **reference**: the scene with every soft division at all six modes, Legendre order
  16, 100 interior points (``sorojax.with_orders``), solved by
  ``sorojax.solve_statics`` (must succeed); its own convergence is the distance from
  the same at order 14. The *true error* of any model is its distance from the
  reference on ``choose_model``'s default quantity: the largest pose distance
  (``pose_distance``: ``max(|dp|, L angle) / L``) over 17 points of every soft
  division and every link's tip, and the closed-loop and prescribed reactions as
  lengths (``reaction_scales``); the tip-pose distance alone is recorded too.
- **adaptive**: ``sorojax.choose_model(linkage, q0, u, tol=tol)`` at its defaults.
  Recorded: its DoF and orders, its error estimate (the verified distance from its
  own reference, order 12 raised by 4 while its estimated error exceeds 0.2 tol),
  the true error, the solves it made and its wall time,
  once cold (first call for the scene and tolerance in this process: includes the
  compiles, except those it shares with an earlier tolerance of the same scene) and
  once again (everything compiled: the choice's own cost); and the warm time of one
  ``solve_statics`` of the chosen model from the scene's guess. The same choice on
  the tip poses alone (``quantity="tips"``, order-12 reference) is run twice: its
  DoF, solves and second-call seconds give the cost of the whole configuration.
- **uniform**: the scene's own modes at uniform order k = 0, 1, 2, ... (default
  points), and, when those cannot reach every tolerance (a mode the scene left out
  matters), all six modes at uniform order k. A sweep stops at order 16 (10 with
  ``--quick``), once the true error is below ``0.1 min(TOLS)``, or when three more
  orders have not halved it (a plateau). The smallest converged uniform model whose
  true error meets the tolerance is the one the adaptive model is compared with.

Warm times: median of repeated public ``solve_statics`` calls after a warm-up (from
the scene's guess, never from the solution), each blocked; compile time apart.
Writes ``benchmarks/results/adequacy.csv`` (one row per scene x tolerance x model),
``adequacy.json`` (environment, references, per scene and tolerance the acceptance
points) and ``adequacy.png`` (true error vs DoF and vs warm time).
"""

import argparse
import csv
import dataclasses
import gc
import json
import math
import statistics
import sys
import time
import warnings
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
from _common import ROOT, environment  # noqa: E402

import sorojax as sj  # noqa: E402
from sorojax import scenes  # noqa: E402
from sorojax._mechanisms import cable_manipulator  # noqa: E402
from sorojax.statics._adequacy import (  # noqa: E402
    _Qoi,
    _tip_poses,
    division_orders,
    pose_distance,
    reference_length,
    transfer_coordinates,
)

sys.path.insert(0, str(ROOT / "tests"))
from rod_references import twisted_end_pose  # noqa: E402

RESULTS_DIR = ROOT / "benchmarks" / "results"
TOLS = (1e-3, 1e-5)
REF_ORDER, REF_CHECK_ORDER, REF_POINTS = 16, 14, 100
ALL_SIX = (1, 1, 1, 1, 1, 1)
QUICK_SCENES = (
    "planar_tip_force",
    "hanging_rod",
    "end_moment",
    "cable_constant",
    "clamped_loop",
    "l_beam",
)


# ------------------------------------------------------------------ scenes
@dataclasses.dataclass
class Scene:
    name: str
    description: str
    linkage: sj.Linkage
    q0: np.ndarray | None = None
    u: np.ndarray | None = None


def _rod(length, radius, E, modes, order, n_divisions=1, rho=1000.0):
    basis = sj.LegendreBasis(modes, order)
    divs = [
        sj.Division(length / n_divisions, sj.CircularSection(radius), basis)
        for _ in range(n_divisions)
    ]
    return sj.SoftLink(divs, sj.Material(E=E, poisson=0.5, rho=rho))


# the convergence benchmark's rod: L 1 m, r 1 cm, E 10 MPa
L1, R1, E1 = 1.0, 0.01, 1e7
EI1 = E1 * math.pi * R1**4 / 4


def planar_tip_force():
    lk = scenes.cantilever(
        L1,
        R1,
        E1,
        modes=(0, 0, 1, 0, 0, 0),
        order=4,
        tip_wrench=[0.0, 0, 0, 0, 5 * EI1 / L1**2, 0],
    )
    return Scene(
        "planar_tip_force",
        "L 1 m, r 1 cm, E 10 MPa; +y dead tip force, PL^2/EI = 5; modes bend-z, order 4",
        lk,
    )


def tip_force_torque_3d():
    w = [EI1 / L1, 0, 0, 0, 2 * EI1 / L1**2, -EI1 / L1**2]
    lk = scenes.cantilever(L1, R1, E1, modes=(1, 1, 1, 0, 0, 0), order=4, tip_wrench=w)
    return Scene(
        "tip_force_torque_3d",
        "same rod; world tip force (0, 2, -1) EI/L^2 and twisting moment EI/L about x;"
        " modes twist + bend, order 4",
        lk,
    )


def hanging_rod():
    lk = scenes.cantilever(
        1.0,
        0.01,
        1e6,
        modes=(0, 1, 1, 0, 0, 0),
        order=4,
        rho=1000.0,
        gravity=(0.0, 0.0, -9.81),
        tip_wrench=[0.0, 0, 0, 0, 0.05, 0],
    )
    return Scene(
        "hanging_rod",
        "horizontal clamp, L 1 m, r 1 cm, E 1 MPa, rho 1000, gravity -z (wL^3/EI = 392)"
        " + 0.05 N tip force +y; modes bend, order 4",
        lk,
    )


def end_moment():
    lk = scenes.cantilever(
        L1,
        R1,
        E1,
        modes=(0, 0, 1, 0, 0, 0),
        order=2,
        tip_wrench=[0.0, 0, 2 * math.pi * EI1 / L1, 0, 0, 0],
    )
    return Scene(
        "end_moment",
        "same rod; end moment 2 pi EI/L about z rolls it into a full circle (exact at"
        " order 0); modes bend-z, order 2",
        lk,
    )


def follower_tip_force():
    rod = _rod(L1, R1, E1, (0, 0, 1, 0, 0, 0), 4)
    pw = sj.PointWrench(1, [0.0, 0, 0, 0, 3 * EI1 / L1**2, 0], follower=True)
    lk = sj.Linkage(rod, point_wrenches=[pw])
    return Scene(
        "follower_tip_force",
        "same rod; follower tip force along local y, PL^2/EI = 3; modes bend-z, order 4",
        lk,
    )


def cable_constant():
    rod = _rod(0.5, 0.01, 1e7, (0, 0, 1, 0, 0, 0), 3)
    cable = sj.Cable(sj.CableSpan(1, sj.ConstantPath(0.008, 0.0)), name="cable")
    lk = sj.Linkage(rod, gravity=(0.0, -9.81, 0.0), actuators=[cable])
    return Scene(
        "cable_constant",
        "L 0.5 m, r 1 cm, E 10 MPa, gravity -y; cable at constant offset 8 mm (+y),"
        " tension 10 N; modes bend-z, order 3",
        lk,
        u=np.array([10.0]),
    )


def cable_helical():
    rod = _rod(0.5, 0.01, 1e7, (1, 1, 1, 0, 0, 0), 3)
    cable = sj.Cable(sj.CableSpan(1, sj.HelicalPath(0.007, 0.5)), name="helix")
    lk = sj.Linkage(rod, gravity=(0.0, 0.0, -9.81), actuators=[cable])
    return Scene(
        "cable_helical",
        "same rod, gravity -z; helical cable, radius 7 mm, half a turn, tension 8 N;"
        " modes twist + bend, order 3",
        lk,
        u=np.array([8.0]),
    )


def cable_arm():
    lk = cable_manipulator()
    return Scene(
        "cable_arm",
        "four-cable tapered arm (examples/cable_manipulator.py: 0.9 m, two divisions,"
        " r 2 -> 1 cm, E 1 MPa, hanging, gravity), tensions (8, 3, 0, 0) N; modes bend,"
        " order 1",
        lk,
        u=np.array([8.0, 3.0, 0.0, 0.0]),
    )


def two_division_mid_load():
    rod = _rod(L1, R1, E1, (1, 1, 1, 0, 0, 0), 3, n_divisions=2)
    lk = sj.Linkage(
        rod,
        point_wrenches=[
            sj.PointWrench(1, [0.0, 0, 0, 0, 0, -2 * EI1 / L1**2], division=1),
            sj.PointWrench(1, [0.0, 0, 0, 0, EI1 / L1**2, 0]),
        ],
    )
    return Scene(
        "two_division_mid_load",
        "same rod in two divisions; -z force 2 EI/L^2 at mid-span, +y tip force"
        " EI/L^2; modes twist + bend, order 3 per division",
        lk,
    )


# tests/test_stability.py's clamped-clamped rod, split in two links so that a link
# tip (mid-span) moves: the QoI is every link's tip pose and the far end is clamped.
E_C, R_C, L_C = 1e6, 0.005, 0.4


def clamped_loop():
    halves = [_rod(L_C / 2, R_C, E_C, ALL_SIX, 6) for _ in range(2)]
    lk = sj.Linkage(
        halves,
        parents=(0, 1),
        closed_loops=[
            sj.ClosedLoopJoint(sj.Joint("N"), 2, 0, g_B=sj.translation(0.9 * L_C))
        ],
    )
    # first clamped-clamped mode w = a/2 (1 - cos(2 pi s / L)); linear theory's
    # amplitude for an end shortening of 0.1 L is a = sqrt(0.4) L / pi (the strain
    # includes the reference elongation 1: a total strain)
    a = math.sqrt(0.4) * L_C / math.pi
    k = 2 * math.pi / L_C

    def strain(offset):
        def f(s):
            return jnp.stack(
                [0.0, 0.0, a / 2 * k**2 * jnp.cos(k * (s + offset)), 1.0, 0.0, 0.0]
            )

        return f

    q0 = sj.strain_coordinates(lk, strain(0.0), link=1, total=True)
    q0 = sj.strain_coordinates(lk, strain(L_C / 2), link=2, q=q0, total=True)
    return Scene(
        "clamped_loop",
        "closed loop: rod (E 1 MPa, r 5 mm, L 0.4 m, two links of 0.2 m) clamped at"
        " both ends, pushed to 0.9 L, from the first buckling mode (linear amplitude);"
        " all six modes, order 6",
        lk,
        q0=np.asarray(q0),
    )


def l_beam():
    return Scene(
        "l_beam",
        "scenes.l_beam: steel L-beam (two 1 m arms, r 1 cm) clamped at both ends,"
        " 2 kN out of plane at the corner (closed loop); modes twist + bend, order 3",
        scenes.l_beam(),
    )


def hybrid_chain():
    return Scene(
        "hybrid_chain",
        "scenes.demo_linkage: rigid 0.3 m bar on a revolute spring + soft rod of two"
        " divisions (0.3 m r 2 -> 1.5 cm, 0.2 m r 1.5 -> 1 cm, E 5 MPa), gravity -y,"
        " 0.5 N follower force; modes bend, orders 1 / 0",
        scenes.demo_linkage(),
    )


def _clamped_rod(order):
    rod = _rod(L_C, R_C, E_C, ALL_SIX, order)
    return rod


def clamped_buckled():
    lk = sj.Linkage(
        _clamped_rod(6),
        closed_loops=[
            sj.ClosedLoopJoint(sj.Joint("N"), 1, 0, g_B=sj.translation(0.8 * L_C))
        ],
    )
    a = math.sqrt(0.8) * L_C / math.pi  # linear theory's amplitude at 0.8 L
    k = 2 * math.pi / L_C

    def strain(s):
        return jnp.stack([0.0, 0.0, a / 2 * k**2 * jnp.cos(k * s), 1.0, 0.0, 0.0])

    return Scene(
        "clamped_buckled",
        "one rod (E 1 MPa, r 5 mm, L 0.4 m) clamped at both ends, the far end at 0.8 L"
        " (closed loop: the tip is held), buckled from the first mode; all six modes,"
        " order 6",
        lk,
        q0=np.asarray(sj.strain_coordinates(lk, strain, total=True)),
    )


def clamped_twisted():
    from sorojax.lie import log_se3

    g = twisted_end_pose(L_C)
    lk = sj.Linkage(
        _clamped_rod(6),
        closed_loops=[sj.ClosedLoopJoint(sj.Joint("N"), 1, 0, g_B=jnp.asarray(g))],
    )
    # the constant strain that reaches the far clamp
    xi = np.asarray(log_se3(jnp.asarray(g))) / L_C
    return Scene(
        "clamped_twisted",
        "the same rod clamped at both ends, the far end at (0.6, 0.3, 0.25) L turned"
        " Rz(0.5) Ry(-0.6) Rx(1.2) (out of plane, twisted; closed loop), from the"
        " constant strain reaching it; all six modes, order 6",
        lk,
        q0=np.asarray(sj.strain_coordinates(lk, jnp.asarray(xi), total=True)),
    )


SCENES = {
    f.__name__: f
    for f in (
        planar_tip_force,
        tip_force_torque_3d,
        hanging_rod,
        end_moment,
        follower_tip_force,
        cable_constant,
        cable_helical,
        cable_arm,
        two_division_mid_load,
        clamped_loop,
        l_beam,
        hybrid_chain,
        clamped_buckled,
        clamped_twisted,
    )
}


# ------------------------------------------------------------------ helpers
def _solve(lk, q0, u):
    return sj.solve_statics(lk, q0, u, warn_unstable=False, throw=False)


def _transfer(scene, target):
    if scene.q0 is None:
        return None
    return transfer_coordinates(scene.linkage, scene.q0, target)


def _warm_time(lk, q0, u, repeats):
    """Median and min of blocked public ``solve_statics`` calls after a warm-up."""
    jax.block_until_ready(_solve(lk, q0, u).q)
    ts = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(_solve(lk, q0, u).q)
        ts.append(time.perf_counter() - t0)
    return statistics.median(ts), min(ts)


def _uniform_orders(lk, k, modes=None):
    return {
        key: tuple(
            k if (m if modes is None else modes[i]) >= 0 else -1
            for i, m in enumerate(o)
        )
        for key, o in division_orders(lk).items()
    }


def _orders_str(orders):
    return "; ".join(
        f"{i}.{k}:" + ",".join(str(x) for x in o)
        for (i, k), o in sorted(orders.items())
    )


class Truth:
    """The over-resolved reference of a scene and the true error of any model.

    The error is on ``choose_model``'s default quantity (``_Qoi``: poses at 17
    points of every soft division and at every link's tip, reactions as lengths);
    ``tip_error`` on the tip poses alone.
    """

    def __init__(self, scene):
        lk = scene.linkage
        self.length = reference_length(lk)
        keys = division_orders(lk)
        self.model = sj.with_orders(
            lk, {key: (REF_ORDER,) * 6 for key in keys}, REF_POINTS
        )
        t0 = time.perf_counter()
        sol = _solve(self.model, _transfer(scene, self.model), scene.u)
        self.seconds = time.perf_counter() - t0
        if int(sol.result._value) != 0:
            raise RuntimeError(
                f"{scene.name}: the reference solve failed ({sol.result})"
            )
        self.q = np.asarray(sol.q)
        self.state = (self.q, np.asarray(sol.lam)[None], np.asarray(sol.efforts)[None])
        self.qoi = _Qoi(self.model, None, self.length)
        self.steps = int(sol.num_steps)
        self.stable = bool(sol.stable)
        self.g = np.asarray(_tip_poses(self.model, jnp.asarray(self.q)[None]))[0]
        check = sj.with_orders(
            lk, {key: (REF_CHECK_ORDER,) * 6 for key in keys}, REF_POINTS
        )
        sol_c = _solve(check, _transfer(scene, check), scene.u)
        self.check_result = int(sol_c.result._value)
        self.self_error = self.error(check, sol_c)
        self.n_dof = self.model.n_dof

    def error(self, lk, sol):
        qoi = _Qoi(lk, None, self.length)
        lam, eff = np.asarray(sol.lam)[None], np.asarray(sol.efforts)[None]
        return float(qoi.against(self.qoi, sol.q, lam, eff, *self.state)[0])

    def tip_error(self, lk, q):
        g = np.asarray(_tip_poses(lk, jnp.asarray(q)[None]))[0]
        return float(pose_distance(g, self.g, self.length).max())


# ------------------------------------------------------------------ per scene
def run_scene(scene, *, kmax, repeats, log):
    lk, u = scene.linkage, scene.u
    out = {"scene": scene.name, "description": scene.description, "n_links": lk.n_links}
    # adaptive first: its cold time then includes its compiles
    choices = {}
    for tol in TOLS:
        t0 = time.perf_counter()
        c = sj.choose_model(lk, scene.q0, u, tol=tol)
        cold = time.perf_counter() - t0
        t0 = time.perf_counter()
        c2 = sj.choose_model(lk, scene.q0, u, tol=tol)
        again = time.perf_counter() - t0
        if c2.n_dof != c.n_dof:
            log(f"  note: repeated choice differs ({c.n_dof} vs {c2.n_dof} DoF)")
        # the same choice on the tip poses alone (order-12 reference): the cost of
        # the whole configuration
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", sj.InsensitiveQuantityWarning)
            sj.choose_model(
                lk, scene.q0, u, tol=tol, quantity="tips", reference_order=12
            )
            t0 = time.perf_counter()
            c_tips = sj.choose_model(
                lk, scene.q0, u, tol=tol, quantity="tips", reference_order=12
            )
            tips_again = time.perf_counter() - t0
        choices[tol] = (c, cold, again, c_tips, tips_again)
        log(
            f"  choose_model tol {tol:.0e}: {c.n_dof} DoF, estimate "
            f"{c.error_estimate:.2e}, {c.num_solves} solves, {cold:.1f} s cold, "
            f"{again:.1f} s again; on tips: {c_tips.n_dof} DoF, "
            f"{c_tips.num_solves} solves, {tips_again:.2f} s again"
        )
    truth = Truth(scene)
    log(
        f"  reference: {truth.n_dof} DoF, {truth.steps} Newton steps, "
        f"{truth.seconds:.1f} s; order {REF_CHECK_ORDER} vs {REF_ORDER}: "
        f"{truth.self_error:.1e} (result {truth.check_result})"
    )
    out["reference"] = {
        "order": REF_ORDER,
        "n_gauss": REF_POINTS,
        "n_dof": truth.n_dof,
        "newton_steps": truth.steps,
        "stable": truth.stable,
        "seconds_incl_compile": truth.seconds,
        "distance_from_order_14": truth.self_error,
        "order_14_result": truth.check_result,
        "length": truth.length,
    }
    rows = []
    for tol, (c, cold, again, c_tips, tips_again) in choices.items():
        q0c = _transfer(scene, c.linkage)
        sol = _solve(c.linkage, q0c, u)
        warm, warm_min = _warm_time(c.linkage, q0c, u, repeats)
        true = truth.error(c.linkage, c.solution)
        ng = sorted(
            {
                d.n_gauss
                for link in c.linkage.links
                if isinstance(link, sj.SoftLink)
                for d in link.divisions
            }
        )
        rows.append(
            {
                "scene": scene.name,
                "tol": tol,
                "model": "adaptive",
                "order": "",
                "orders": _orders_str(c.orders),
                "n_dof": c.n_dof,
                "n_gauss": "/".join(map(str, ng)),
                "true_error": true,
                "error_estimate": c.error_estimate,
                "ratio_estimate_true": c.error_estimate / true
                if true > 0
                else math.inf,
                "choice_reference_error": c.reference_error,
                "meets_tol": true <= tol,
                "result": int(sol.result._value),
                "newton_steps": int(sol.num_steps),
                "warm_s": warm,
                "warm_min_s": warm_min,
                "choice_solves": c.num_solves,
                "choice_seconds_cold": cold,
                "choice_seconds_again": again,
                "choice_history": repr(c.history),
                "reference_order": max(
                    o for v in division_orders(c.reference).values() for o in v
                ),
                "tip_error": truth.tip_error(c.linkage, c.q),
                "tips_n_dof": c_tips.n_dof,
                "tips_solves": c_tips.num_solves,
                "tips_seconds_again": tips_again,
                "tips_quantity": c_tips.quantity,
            }
        )
    # uniform sweeps
    uniform = []

    def sweep(kind, modes):
        errs = []
        for k in range(kmax + 1):
            m = sj.with_orders(lk, _uniform_orders(lk, k, modes))
            q0m = _transfer(scene, m)
            t0 = time.perf_counter()
            sol = _solve(m, q0m, u)
            first = time.perf_counter() - t0
            res = int(sol.result._value)
            err_any = truth.error(m, sol)
            err = err_any if res == 0 and np.isfinite(err_any) else math.inf
            warm, warm_min = _warm_time(m, q0m, u, repeats)
            uniform.append(
                {
                    "model": kind,
                    "order": k,
                    "orders": _orders_str(_uniform_orders(lk, k, modes)),
                    "n_dof": m.n_dof,
                    "n_gauss": "/".join(
                        map(
                            str,
                            sorted(
                                {
                                    d.n_gauss
                                    for link in m.links
                                    if isinstance(link, sj.SoftLink)
                                    for d in link.divisions
                                }
                            ),
                        )
                    ),
                    "true_error": err,
                    "true_error_any_result": err_any,
                    "result": res,
                    "newton_steps": int(sol.num_steps),
                    "warm_s": warm,
                    "warm_min_s": warm_min,
                    "first_call_s": first,
                }
            )
            errs.append(err)
            log(
                f"  {kind} k={k:2d}: {m.n_dof:4d} DoF, error {err:.2e}"
                f" (result {res}), warm {1e3 * warm:.2f} ms"
            )
            if err < 0.1 * min(TOLS):
                break
            if k >= 3 and err > 0.5 * errs[-4]:
                break  # plateau: three more orders did not halve it
        return min(errs)

    best = sweep("uniform_scene", None)
    if best > min(TOLS):
        sweep("uniform_all6", ALL_SIX)
    for tol in TOLS:
        for r in uniform:
            rows.append(
                {
                    "scene": scene.name,
                    "tol": tol,
                    **r,
                    "meets_tol": r["true_error"] <= tol,
                }
            )
    # acceptance points
    summary = {}
    for tol, (c, cold, again, c_tips, tips_again) in choices.items():
        a = next(r for r in rows if r["tol"] == tol and r["model"] == "adaptive")
        meeting = [r for r in uniform if r["true_error"] <= tol]
        by_kind = {
            kind: min((r["n_dof"] for r in meeting if r["model"] == kind), default=None)
            for kind in ("uniform_scene", "uniform_all6")
        }
        u_best = min((r for r in meeting), key=lambda r: r["n_dof"], default=None)
        ratio = a["ratio_estimate_true"]
        summary[f"{tol:.0e}"] = {
            "adaptive_n_dof": a["n_dof"],
            "adaptive_orders": a["orders"],
            "adaptive_true_error": a["true_error"],
            "adaptive_error_estimate": a["error_estimate"],
            "ratio_estimate_true": ratio,
            "adaptive_warm_s": a["warm_s"],
            "uniform_meeting_n_dof": None if u_best is None else u_best["n_dof"],
            "uniform_meeting_model": None
            if u_best is None
            else f"{u_best['model']} k={u_best['order']}",
            "uniform_meeting_warm_s": None if u_best is None else u_best["warm_s"],
            "uniform_meeting_n_dof_by_kind": by_kind,
            "choice_solves": c.num_solves,
            "choice_seconds_cold": cold,
            "choice_seconds_again": again,
            "reference_order": a["reference_order"],
            "adaptive_tip_error": a["tip_error"],
            "tips_n_dof": c_tips.n_dof,
            "tips_solves": c_tips.num_solves,
            "tips_seconds_again": tips_again,
            "tips_quantity": c_tips.quantity,
            "pass_meets_tol": a["true_error"] <= tol,
            "pass_fewer_dof": u_best is None or a["n_dof"] < u_best["n_dof"],
            "pass_fewer_or_equal_dof": u_best is None or a["n_dof"] <= u_best["n_dof"],
            "pass_estimate_within_10x": 0.1 <= ratio <= 10.0,
            "true_error_at_round_off": a["true_error"] < 1e-12,
        }
    out["summary"] = summary
    return out, rows


# ------------------------------------------------------------------ output
def plot(rows, path):
    """True error vs DoF and vs warm time (rows as written to the CSV)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(14, 6.6))
    colors = [*plt.get_cmap("tab10").colors, "k", "gold", "lime", "navy"]
    floor = 1e-16
    names = list(dict.fromkeys(r["scene"] for r in rows))
    for n, name in enumerate(names):
        color = colors[n % len(colors)]
        mine = [r for r in rows if r["scene"] == name and r["tol"] == TOLS[0]]
        for kind, style in (("uniform_scene", "-"), ("uniform_all6", "--")):
            us = [
                r for r in mine if r["model"] == kind and np.isfinite(r["true_error"])
            ]
            if not us:
                continue
            e = [max(r["true_error"], floor) for r in us]
            label = name if kind == "uniform_scene" else None
            axes[0].loglog(
                [r["n_dof"] for r in us],
                e,
                style,
                color=color,
                lw=1,
                marker=".",
                label=label,
            )
            axes[1].loglog(
                [1e3 * r["warm_s"] for r in us], e, style, color=color, lw=1, marker="."
            )
        for tol, marker in zip(TOLS, ("o", "*"), strict=True):
            a = next(
                r
                for r in rows
                if r["scene"] == name and r["tol"] == tol and r["model"] == "adaptive"
            )
            e = max(a["true_error"], floor)
            kw = dict(
                marker=marker,
                color=color,
                ms=11 if marker == "*" else 8,
                mec="k",
                mew=0.7,
                ls="none",
            )
            axes[0].loglog([a["n_dof"]], [e], **kw)
            axes[1].loglog([1e3 * a["warm_s"]], [e], **kw)
    for ax in axes:
        for tol in TOLS:
            ax.axhline(tol, color="k", lw=0.8, ls=":")
        ax.set_ylabel("true error (configuration distance / L)")
        ax.grid(True, which="both", alpha=0.25)
    axes[0].set_xlabel("DoF")
    axes[1].set_xlabel("warm solve_statics time [ms] (CPU)")
    axes[0].set_title(
        "error vs DoF: uniform orders (solid: scene modes, dashed: all six)"
        "\nadaptive: o tol 1e-3, * tol 1e-5",
        fontsize=10,
    )
    axes[1].set_title("error vs warm time", fontsize=10)
    fig.legend(loc="lower center", ncol=7, fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0.08, 1, 1))
    fig.savefig(path, dpi=120)


def print_table(results):
    head = (
        f"{'scene':24s} {'tol':>6s} {'adapt':>5s} {'unif':>5s} {'true err':>9s} "
        f"{'estimate':>9s} {'ratio':>6s} {'solv':>4s} {'cold s':>6s} {'again s':>7s}"
        f" {'warm ms':>8s} {'unif ms':>8s}  pass (tol, dof<, dof<=, 10x)"
    )
    print(head)
    print("-" * len(head))
    for res in results:
        for tol, s in res["summary"].items():
            un = s["uniform_meeting_n_dof"]
            uw = s["uniform_meeting_warm_s"]
            flags = "".join(
                "Y" if s[k] else "n"
                for k in (
                    "pass_meets_tol",
                    "pass_fewer_dof",
                    "pass_fewer_or_equal_dof",
                    "pass_estimate_within_10x",
                )
            )
            print(
                f"{res['scene']:24s} {tol:>6s} {s['adaptive_n_dof']:5d} "
                f"{'-' if un is None else un:>5} {s['adaptive_true_error']:9.2e} "
                f"{s['adaptive_error_estimate']:9.2e} {s['ratio_estimate_true']:6.2f} "
                f"{s['choice_solves']:4d} {s['choice_seconds_cold']:6.1f} "
                f"{s['choice_seconds_again']:7.2f} {1e3 * s['adaptive_warm_s']:8.2f} "
                f"{'-' if uw is None else f'{1e3 * uw:.2f}':>8}  {flags}"
            )


def _read_csv(path):
    rows = []
    with open(path) as fh:
        for r in csv.DictReader(fh):
            for k in ("tol", "true_error", "warm_s"):
                r[k] = float(r[k])
            r["n_dof"] = int(r["n_dof"])
            rows.append(r)
    return rows


def _finite(obj):
    """JSON-safe copy: non-finite floats become None."""
    if isinstance(obj, dict):
        return {str(k): _finite(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_finite(v) for v in obj]
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def merge(folders, out):
    """One ``adequacy.{csv,json,png}`` from the runs in ``folders`` (scene order)."""
    metas = [json.loads((f / "adequacy.json").read_text()) for f in folders]
    rows, fields = [], []
    for f in folders:
        with open(f / "adequacy.csv") as fh:
            reader = csv.DictReader(fh)
            fields += [k for k in reader.fieldnames if k not in fields]
            rows += list(reader)
    order = {name: k for k, name in enumerate(SCENES)}
    rows.sort(key=lambda r: order[r["scene"]])
    scenes = sorted(
        (sc for m in metas for sc in m["scenes"]), key=lambda sc: order[sc["scene"]]
    )
    meta = dict(metas[0])
    meta["environment"] = dict(
        metas[0]["environment"], scenes=[sc["scene"] for sc in scenes]
    )
    meta["runs"] = [
        {"scenes": m["environment"]["scenes"], "total_s": m["total_s"]} for m in metas
    ]
    meta["total_s"] = max(m["total_s"] for m in metas)
    meta["failed_points"] = [p for m in metas for p in m["failed_points"]]
    meta["scenes"] = scenes
    out.mkdir(parents=True, exist_ok=True)
    with open(out / "adequacy.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=fields)
        w.writeheader()
        w.writerows(rows)
    (out / "adequacy.json").write_text(json.dumps(meta, indent=2))
    plot(_read_csv(out / "adequacy.csv"), out / "adequacy.png")
    print(f"Merged {len(scenes)} scenes into {out}; failed points:")
    for p in meta["failed_points"]:
        print("  ", p)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--quick",
        action="store_true",
        help=f"scenes {', '.join(QUICK_SCENES)}; orders <= 10; 3 repeats",
    )
    ap.add_argument("--scenes", nargs="*", default=None, choices=list(SCENES))
    ap.add_argument("--kmax", type=int, default=None, help="highest uniform order")
    ap.add_argument("--repeats", type=int, default=None)
    ap.add_argument("--out", type=Path, default=RESULTS_DIR, help="output folder")
    ap.add_argument(
        "--plot-only",
        action="store_true",
        help="redraw adequacy.png from the CSV in --out (no solves)",
    )
    ap.add_argument(
        "--merge",
        nargs="*",
        type=Path,
        default=None,
        help="merge the results of runs in these folders (e.g. one scene each, run"
        " in parallel) into --out (no solves)",
    )
    args = ap.parse_args(argv)
    if args.plot_only:
        plot(_read_csv(args.out / "adequacy.csv"), args.out / "adequacy.png")
        return
    if args.merge:
        merge(args.merge, args.out)
        return
    names = args.scenes or (list(QUICK_SCENES) if args.quick else list(SCENES))
    kmax = args.kmax if args.kmax is not None else (10 if args.quick else 16)
    repeats = args.repeats or (3 if args.quick else 7)
    env = environment(
        quick=args.quick,
        scenes=names,
        kmax=kmax,
        repeats=repeats,
        sorojax_file=sj.__file__,
    )
    print(
        f"jax {env['jax_version']} on {env['devices']}, {env['cpu_count']} CPUs, "
        f"load average {env['load_average_at_start'][0]:.1f}"
    )
    t_start = time.perf_counter()
    results, rows = [], []
    warnings.simplefilter("ignore", sj.UnstableEquilibriumWarning)
    for name in names:
        scene = SCENES[name]()
        print(f"\n{name}: {scene.description}", flush=True)
        t0 = time.perf_counter()
        res, rs = run_scene(
            scene, kmax=kmax, repeats=repeats, log=lambda s: print(s, flush=True)
        )
        res["seconds"] = time.perf_counter() - t0
        print(f"  ({res['seconds']:.0f} s)", flush=True)
        results.append(res)
        rows.extend(rs)
        # hundreds of compiled programs in one process exhausted LLVM's memory
        # (segfault in the 12-scene run): drop them between scenes
        jax.clear_caches()
        gc.collect()
    total = time.perf_counter() - t_start
    print(f"\nTotal {total:.0f} s\n")
    print_table(results)
    fails = [
        (res["scene"], tol, k)
        for res in results
        for tol, s in res["summary"].items()
        for k in ("pass_meets_tol", "pass_fewer_dof", "pass_estimate_within_10x")
        if not s[k]
    ]
    print("\nFailed acceptance points:" if fails else "\nAll acceptance points pass.")
    for f in fails:
        print(f"  {f[0]} tol {f[1]}: {f[2]}")

    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    stem = "adequacy"
    fields = [
        "scene",
        "tol",
        "model",
        "order",
        "orders",
        "n_dof",
        "n_gauss",
        "true_error",
        "error_estimate",
        "ratio_estimate_true",
        "choice_reference_error",
        "meets_tol",
        "result",
        "newton_steps",
        "warm_s",
        "warm_min_s",
        "first_call_s",
        "true_error_any_result",
        "choice_solves",
        "choice_seconds_cold",
        "choice_seconds_again",
        "choice_history",
        "reference_order",
        "tip_error",
        "tips_n_dof",
        "tips_solves",
        "tips_seconds_again",
        "tips_quantity",
    ]
    with open(out / f"{stem}.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=fields)
        w.writeheader()
        w.writerows(rows)
    env["load_average_at_end"] = list(__import__("os").getloadavg())
    meta = {
        "environment": env,
        "tols": TOLS,
        "reference": {
            "order": REF_ORDER,
            "n_gauss": REF_POINTS,
            "check_order": REF_CHECK_ORDER,
            "modes": ALL_SIX,
        },
        "total_s": total,
        "failed_points": [list(f) for f in fails],
        "scenes": results,
    }
    (out / f"{stem}.json").write_text(json.dumps(_finite(meta), indent=2))
    plot(rows, out / f"{stem}.png")
    print(f"Wrote {out / stem}.{{csv,json,png}}")


if __name__ == "__main__":
    main()
