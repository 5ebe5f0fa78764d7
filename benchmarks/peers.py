"""Peer comparison: SoRoSim's free-fall rod in sorojax, soromox and PyElastica.

Run from the repository root with the benchmark environment (sorojax installed
editable next to the two peers; see ``benchmarks/README.md``, section ``peers.py``)::

    python3 -m venv .venv-bench
    .venv-bench/bin/pip install -e . pyelastica soromox
    .venv-bench/bin/python benchmarks/peers.py            # full run
    .venv-bench/bin/python benchmarks/peers.py --quick    # short spans, 1 timed repeat

The rod (SoRoSim dynamics tutorial): L 0.5 m, circular radius 2 -> 1 cm (linear), E 1 MPa,
G = E/3, rho 1000 kg/m^3, clamped at the base, straight reference along x, released at
rest from a uniform pre-bend of 1 rad/m about y, gravity 9.81 m/s^2 along -z.

Two comparisons:

1. **Matched tip accuracy, undamped** (the same Cosserat PDE in the three codes: bending,
   twist, stretch and shear). A tight sorojax reference (order 6, ``dopri8`` at rtol 1e-10,
   checked against rtol 1e-11 and against 32 Gauss points instead of 16) gives the tip
   trajectory; every code is then run at the cheapest setting of a ladder (sorojax: rtol;
   soromox: constant step of its default explicit rollout, ``Tsit5``; PyElastica: number of
   elements, each with its largest stable ``PositionVerlet`` step) whose tip error
   ``max_t |tip - tip_ref| / L`` is within the target, and that setting is timed.
   sorojax and soromox use all six strains at the lowest Legendre order (of
   ``MATCHED_ORDERS``) whose tight-tolerance tip differs from the reference by less
   than half the target (measured: orders 3 / 4 / 5 differ by 1.1e-2 / 6.4e-3 /
   3.4e-3 L).
2. **Speed, 5 s damped**: sorojax's 12-DoF damped rod (``free_fall_rod(order=3,
   eta=1e4)``, Kelvin-Voigt), soromox with the same model (its material damping has the
   same form), PyElastica with its own damping (``AnalyticalLinearDamper``, uniform
   constant fitted to the first-mode decay rate of the Kelvin-Voigt rod: a different
   damping model, so its run is speed only).

Compile / first-call overhead is reported separately from warm time; warm times are the
median of repeated runs after a warm-up (sorojax and soromox end each run with
``jax.block_until_ready``). Prints a table and writes ``benchmarks/results/peers.json``;
the reference trajectory is cached in ``benchmarks/results/peers_reference.npz``.
"""

import argparse
import inspect
import json
import math
import os
import statistics
import sys
import time
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import diffrax  # noqa: E402
import equinox as eqx  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
from _common import environment as base_environment  # noqa: E402
from _common import git_state  # noqa: E402

import sorojax  # noqa: E402
from sorojax.scenes import free_fall_q0, free_fall_rod  # noqa: E402

try:  # optional peers (the `bench` extra)
    import soromox
    from soromox.systems import (
        GVS,
        GVSSegment,
        JointSpec,
        LinearProfile,
        LinkSpec,
        StrainBasisSpec,
        SystemState,
    )
except ImportError as exc:  # pragma: no cover - depends on the environment
    soromox = None
    SOROMOX_IMPORT_ERROR = repr(exc)
else:
    SOROMOX_IMPORT_ERROR = None
try:
    import elastica
except ImportError as exc:  # pragma: no cover - depends on the environment
    elastica = None
    ELASTICA_IMPORT_ERROR = repr(exc)
else:
    ELASTICA_IMPORT_ERROR = None

RESULTS_DIR = Path(__file__).resolve().parent / "results"
ROOT = Path(__file__).resolve().parent.parent

# The rod.
L, R_BASE, R_TIP, E, RHO = 0.5, 0.02, 0.01, 1e6, 1000.0
G = E / 3.0  # poisson 0.5
ETA = 1e4  # Kelvin-Voigt damping [Pa s] of the damped case
KAPPA0 = 1.0  # initial uniform curvature about y [1/m]
GRAVITY = (0.0, 0.0, -9.81)
ALL_MODES = (1, 1, 1, 1, 1, 1)
BEND_TWIST = (1, 1, 1, 0, 0, 0)
SOROSIM_DAMPED_S = 1.5  # SoRoSim (MATLAB, ode15s), 5 s damped free-fall rod
TARGET_DAMPED_S = 0.15

# Ladders searched for the matched-accuracy settings (cheapest first).
RTOL_LADDER = (1e-3, 3e-4, 1e-4, 3e-5, 1e-5, 3e-6, 1e-6, 1e-7, 1e-8)
# sorojax's constant-step solvers: steps [s] (dt = 0.01 / k, as the peers' ladder)
DT_LADDER = (5e-3, 10 / 3 * 1e-3, 2.5e-3, 2e-3, 1e-3 / 0.6, 1.25e-3, 1e-3, 5e-4, 2.5e-4)
# Steps per 10 ms save interval (dt = 0.01 / k) for the fixed-step peers.
K_LADDER = (2, 3, 4, 5, 6, 8, 10, 12, 16, 20, 25, 32, 40, 50, 64, 80, 100, 128, 160)
K_LADDER += (200, 256, 320, 400, 500, 640, 800, 1000)
N_ELEMENTS_LADDER = (10, 15, 20, 30, 40, 60, 80, 120, 160)
SAVE_DT = 0.01
# Basis orders (all six strains) tried for the matched-accuracy runs: the lowest whose
# tight-tolerance tip differs from the order-6 reference by < half the target is used
# (measured 1.1e-2 / 6.4e-3 / 3.4e-3 L at orders 3 / 4 / 5: none reaches 1e-3).
MATCHED_ORDERS = (3, 4, 5)


# --------------------------------------------------------------------------- helpers


def tip_error(tips, ref):
    """max over save times of |tip - tip_ref| / L (inf if not finite)."""
    tips = np.asarray(tips)
    if tips.shape != ref.shape or not np.all(np.isfinite(tips)):
        return math.inf
    return float(np.max(np.linalg.norm(tips - ref, axis=1)) / L)


def timed_runs(run, repeats, budget_s):
    """Call ``run()`` (warm) up to ``repeats`` times within ``budget_s``; wall times."""
    ts = []
    t_start = time.perf_counter()
    for _ in range(repeats):
        t0 = time.perf_counter()
        run()
        ts.append(time.perf_counter() - t0)
        if time.perf_counter() - t_start > budget_s:
            break
    return ts


def summary(ts):
    return {
        "warm_median_s": statistics.median(ts),
        "warm_min_s": min(ts),
        "warm_all_s": ts,
        "repeats": len(ts),
    }


def arc_tip(s):
    """Tip of the initial arc (curvature KAPPA0 about y) at arc length s."""
    k = KAPPA0
    return np.array([math.sin(k * s) / k, 0.0, -(1.0 - math.cos(k * s)) / k])


# --------------------------------------------------------------------------- sorojax
def sorojax_rod(modes, order, eta=0.0, n_gauss=None):
    rod = free_fall_rod(order=order, eta=eta, modes=modes, n_gauss=n_gauss)
    # 1 rad/m about y, unstretched, as a total strain (reference elongation 1
    # included); ``free_fall_q0`` gives the same q as a deviation from the reference.
    q0 = sorojax.strain_coordinates(rod, [0.0, KAPPA0, 0.0, 1.0, 0.0, 0.0], total=True)
    if modes == BEND_TWIST:
        assert np.allclose(q0, free_fall_q0(rod), atol=1e-12)
    tip0 = np.asarray(sorojax.tip_pose(rod, q0))[:3, 3]
    assert np.allclose(tip0, arc_tip(L), atol=1e-9), tip0
    return rod, q0


class SorojaxCase:
    """``sorojax.simulate`` of one rod; ``run`` returns the trajectory (blocked)."""

    def __init__(self, rod, q0, t1, n_save, solver, max_steps=200_000):
        self.rod, self.q0, self.t1, self.n_save = rod, q0, t1, n_save
        self.solver, self.max_steps = solver, max_steps
        self._tips = jax.jit(lambda q: jax.vmap(lambda x: tip_of(rod, x))(q))

    def run(self, rtol, atol, dt=None):
        """Adaptive at ``rtol``, ``atol``; with ``dt`` constant steps of it."""
        steps = dict(rtol=rtol, atol=atol) if dt is None else dict(dt0=dt)
        traj = sorojax.simulate(
            self.rod,
            self.t1,
            self.q0,
            solver=self.solver,
            n_save=self.n_save,
            max_steps=self.max_steps,
            throw=False,
            **steps,
        )
        return jax.block_until_ready(traj)

    def tips(self, traj):
        if int(traj.result._value) != 0:
            return np.full((self.n_save, 3), np.nan)
        return np.asarray(self._tips(traj.q))


def tip_of(rod, q):
    return sorojax.tip_pose(rod, q)[:3, 3]


def sorojax_reference(t1, n_save, cache, recompute):
    """Tight reference tip trajectory of the undamped rod (all six strain modes)."""
    key = {"t1": t1, "n_save": n_save, "version": 4}
    if cache.exists() and not recompute:
        data = np.load(cache, allow_pickle=False)
        meta = json.loads(str(data["meta"]))
        if meta.get("key") == key:
            print(f"    reference loaded from {cache.relative_to(ROOT)}")
            return data["tips"], meta
    runs = {
        # name: (order, n_gauss, solver, rtol = atol)
        "reference: order 6, dopri8 rtol 1e-10": (6, None, "dopri8", 1e-10),
        "check time: order 6, dopri8 rtol 1e-11": (6, None, "dopri8", 1e-11),
        "check quadrature: order 6, 32 Gauss points": (6, 32, "dopri8", 1e-10),
        **{
            f"candidate model: order {k}, dopri8 rtol 1e-10": (k, None, "dopri8", 1e-10)
            for k in MATCHED_ORDERS
        },
    }
    tips, meta = {}, {"key": key, "runs": {}}
    for name, (order, ng, solver, rtol) in runs.items():
        rod, q0 = sorojax_rod(ALL_MODES, order, n_gauss=ng)
        case = SorojaxCase(rod, q0, t1, n_save, solver, max_steps=10**6)
        t0 = time.perf_counter()
        traj = case.run(rtol, rtol)
        tips[name] = case.tips(traj)
        meta["runs"][name] = {
            "n_dof": rod.n_dof,
            "order": order,
            "n_gauss": ng,
            "solver": solver,
            "rtol": rtol,
            "atol": rtol,
            "steps": int(traj.num_steps),
            "wall_s_incl_compile": time.perf_counter() - t0,
        }
        print(f"    {name}: {int(traj.num_steps)} steps, {meta['runs'][name]}")
    ref_name = next(iter(runs))
    ref = tips[ref_name]
    for name in runs:
        meta["runs"][name]["tip_difference_vs_reference"] = tip_error(tips[name], ref)
    meta["git"] = git_state()
    RESULTS_DIR.mkdir(parents=True, exist_ok=True)
    np.savez(cache, tips=ref, meta=json.dumps(meta))
    return ref, meta


# --------------------------------------------------------------------------- soromox
def soromox_robot(modes, order, eta=None, n_gauss=10):
    link = LinkSpec.circular(
        length=L,
        radius=LinearProfile(R_BASE, R_TIP),
        density=RHO,
        reference_strain=[0.0, 0.0, 0.0, 1.0, 0.0, 0.0],
        young_modulus=E,
        shear_modulus=G,  # soromox takes poisson < 0.5 only; G = E/3 directly
        material_damping_coefficient=eta,
    )
    segment = GVSSegment(
        link=link,
        joint=JointSpec.fixed(),
        basis=StrainBasisSpec("legendre", list(modes), order),
        num_gauss_points=n_gauss,
    )
    robot = GVS.from_segments(
        [segment],
        gravity=jnp.asarray(GRAVITY),
        base_pose=jnp.asarray([0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0]),  # identity, at 0
    )
    n = robot.num_coordinates
    q0 = np.zeros(n)
    # Legendre P0 = 1: the constant kappa_y coefficient follows the kappa_x block.
    q0[modes[0] * (order + 1)] = KAPPA0
    q0 = jnp.asarray(q0)
    tip0 = np.asarray(robot.forward_kinematics(q0, L))[:3, 3]
    assert np.allclose(tip0, arc_tip(L), atol=1e-9), tip0
    return robot, q0


class SoromoxCase:
    """soromox's default open-loop rollout (diffrax Tsit5, constant step), jitted."""

    def __init__(self, robot, q0, t1, n_save, dt_min):
        self.robot, self.n_save = robot, n_save
        self.y0 = jnp.concatenate([q0, jnp.zeros_like(q0)])
        save_ts = jnp.linspace(0.0, t1, n_save)
        max_steps = int(math.ceil(t1 / dt_min)) + 16
        n = robot.num_coordinates

        @eqx.filter_jit
        def roll(robot, y0, dt):
            out = robot.rollout_to(
                SystemState(t=0.0, y=y0),
                t1=t1,
                solver_dt=dt,
                save_ts=save_ts,
                max_steps=max_steps,
            )
            return out.y

        self._roll = roll
        self._tips = jax.jit(
            lambda ys: jax.vmap(lambda y: robot.forward_kinematics(y[:n], L)[:3, 3])(ys)
        )

    def run(self, dt):
        return jax.block_until_ready(self._roll(self.robot, self.y0, jnp.asarray(dt)))

    def tips(self, ys):
        return np.asarray(self._tips(ys))


# --------------------------------------------------------------------------- PyElastica
if elastica is not None:

    class ElasticaSim(
        elastica.BaseSystemCollection,
        elastica.Constraints,
        elastica.Forcing,
        elastica.Damping,
    ):
        pass


def elastica_build(n, damping=None, dt=None):
    """The rod in PyElastica with n elements; returns (simulator, rod, setup seconds).

    Clamp: ``OneEndFixedBC`` fixes node 0 and the directors of element 0. A director
    lives at its element's centre, so the clamped frame is put at the physical base:
    element 0 is centred on x = 0 (node 0 at -h/2, h = L / (n - 1/2)) and the free tip
    (node n) is at arc length L. Radius per element from its centre (linear taper).
    Initial state: straight reference (rest strains zero, rest lengths h), released from
    a polygon whose element directors are turned by KAPPA0 * s_i about y (discrete
    curvature exactly KAPPA0, no stretch or shear). Shear stiffness set to G A (PyElastica
    default alpha_c G A with alpha_c = 27/28) to match the GVS codes.
    """
    t0 = time.perf_counter()
    h = L / (n - 0.5)
    s_c = np.arange(n) * h  # element centres (arc length from the clamp)
    phi = KAPPA0 * s_c
    tangent = np.stack([np.cos(phi), np.zeros(n), -np.sin(phi)])
    pos = np.zeros((3, n + 1))
    pos[0, 0] = -h / 2
    pos[:, 1:] = pos[:, :1] + np.cumsum(h * tangent, axis=1)
    directors = np.zeros((3, 3, n))
    directors[0] = np.array([0.0, 1.0, 0.0])[:, None]  # d1 = y (bending about d1)
    directors[1] = np.stack([np.sin(phi), np.zeros(n), np.cos(phi)])
    directors[2] = tangent
    radius = R_BASE + (R_TIP - R_BASE) * np.clip(s_c / L, 0.0, 1.0)
    rod = elastica.CosseratRod.straight_rod(
        n,
        np.array([-h / 2, 0.0, 0.0]),
        np.array([1.0, 0.0, 0.0]),
        np.array([0.0, 1.0, 0.0]),
        n * h,
        radius,
        RHO,
        youngs_modulus=E,
        shear_modulus=G,
        position=pos,
        directors=directors,
    )
    area = np.pi * radius**2
    rod.shear_matrix[0, 0, :] = G * area
    rod.shear_matrix[1, 1, :] = G * area
    sim = ElasticaSim()
    sim.append(rod)
    sim.constrain(rod).using(
        elastica.OneEndFixedBC,
        constrained_position_idx=(0,),
        constrained_director_idx=(0,),
    )
    sim.add_forcing_to(rod).using(elastica.GravityForces, acc_gravity=np.array(GRAVITY))
    if damping is not None:
        sim.dampen(rod).using(
            elastica.AnalyticalLinearDamper,
            uniform_damping_constant=damping,
            time_step=dt,
        )
    sim.finalize()
    return sim, rod, time.perf_counter() - t0


def elastica_run(n, t1, k, damping=None):
    """Integrate to t1 with dt = SAVE_DT / k; (tips at every SAVE_DT, wall s, setup s)."""
    dt = SAVE_DT / k
    sim, rod, setup = elastica_build(n, damping, dt)
    stepper = elastica.PositionVerlet()
    n_int = int(round(t1 / SAVE_DT))
    tips = np.empty((n_int + 1, 3))
    tips[0] = rod.position_collection[:, -1]
    t = 0.0
    t0 = time.perf_counter()
    for i in range(n_int):
        for _ in range(k):
            t = stepper.step(sim, t, dt)
        tips[i + 1] = rod.position_collection[:, -1]
    return tips, time.perf_counter() - t0, setup


# --------------------------------------------------------------------------- searches
def largest_stable_k(run_short, ok):
    """First k of K_LADDER (largest step) whose short run is stable."""
    for k in K_LADDER:
        if ok(run_short(k)):
            return k
    raise RuntimeError("no stable step in the ladder")


def matched_order(ref_meta, target):
    """Lowest candidate order whose basis error is below half the target (or None)."""
    for k in MATCHED_ORDERS:
        run = ref_meta["runs"].get(f"candidate model: order {k}, dopri8 rtol 1e-10")
        if run and run["tip_difference_vs_reference"] < 0.5 * target:
            return k
    return None


def bench_sorojax_matched(ref, t1, n_save, target, solvers, repeats, budget_s, order):
    rows = []
    rod, q0 = sorojax_rod(ALL_MODES, order)
    for solver in solvers:
        case = SorojaxCase(rod, q0, t1, n_save, solver)
        # constant-step solvers climb a ladder of steps, the others one of tolerances
        constant = not isinstance(
            sorojax.integrate.SOLVERS[solver](), diffrax.AbstractAdaptiveSolver
        )
        ladder = (
            [(None, None, dt) for dt in DT_LADDER]
            if constant
            else [(r, r, None) for r in RTOL_LADDER]
        )
        # Probe: cost of the loosest setting on a twentieth of the span.
        probe = SorojaxCase(rod, q0, t1 / 20, max(2, n_save // 20), solver)
        t0 = time.perf_counter()
        probe.run(*ladder[0])
        first_probe = time.perf_counter() - t0
        t0 = time.perf_counter()
        probe.run(*ladder[0])
        est = 20 * (time.perf_counter() - t0)
        row = {
            "code": "sorojax",
            "case": "undamped, matched accuracy",
            "solver": solver,
            "n_dof": rod.n_dof,
            "modes": ALL_MODES,
            "order": order,
            "probe_estimate_s": est,
        }
        if est > budget_s:
            row["skipped"] = (
                f"estimated {est:.0f} s per run on the full span (> budget "
                f"{budget_s:.0f} s; probe on t1/20 took {est / 20:.1f} s warm, "
                f"{first_probe:.1f} s with compile)"
            )
            print(f"    sorojax {solver}: {row['skipped']}")
            rows.append(row)
            continue
        chosen, scan = None, []
        for rtol, atol, dt in ladder:
            t0 = time.perf_counter()
            traj = case.run(rtol, atol, dt)
            first = time.perf_counter() - t0
            err = tip_error(case.tips(traj), ref)
            scan.append(
                {
                    "rtol": rtol,
                    "atol": atol,
                    "dt": dt,
                    "tip_error": err,
                    "steps": int(traj.num_steps),
                    "first_call_s": first,
                }
            )
            how = f"dt {dt:.3g}" if constant else f"rtol {rtol:g}"
            print(
                f"    sorojax {solver} {how}: err {err:.2e}, "
                f"{int(traj.num_steps)} steps, {first:.2f} s"
            )
            if err <= target:
                chosen = scan[-1]
                break
            if first > budget_s:
                break
        row["scan"] = scan
        if chosen is None:
            row["skipped"] = "target not reached within the rtol ladder / budget"
            rows.append(row)
            continue
        # Timing at the chosen rtol: compile measured on a fresh trace of the same call.
        first_call = scan[0]["first_call_s"]
        ts = timed_runs(
            lambda c=chosen, case=case: case.run(c["rtol"], c["atol"], c["dt"]),
            repeats,
            budget_s,
        )
        row.update(summary(ts))
        row.update(
            {
                "settings": (
                    f"{solver}, constant dt = {chosen['dt']:.3g} s"
                    if constant
                    else f"{solver}, rtol = atol = {chosen['rtol']:g}"
                ),
                "rtol": chosen["rtol"],
                "atol": chosen["atol"],
                "dt": chosen["dt"],
                "steps": chosen["steps"],
                "tip_error": chosen["tip_error"],
                "first_call_s": first_call,
            }
        )
        # compile ~ first call at the loosest rtol minus a warm call at that rtol
        warm_first = timed_runs(
            lambda case=case, loosest=ladder[0]: case.run(*loosest),
            1,
            budget_s,
        )[0]
        row["compile_s"] = max(0.0, first_call - warm_first)
        rows.append(row)
    return rows


def bench_soromox_matched(ref, t1, n_save, target, repeats, budget_s, short, order):
    robot, q0 = soromox_robot(ALL_MODES, order)
    dts = [SAVE_DT / k for k in K_LADDER]
    case = SoromoxCase(robot, q0, t1, n_save, min(dts))
    n_short = int(round(short / SAVE_DT)) + 1
    short_case = SoromoxCase(robot, q0, short, n_short, min(dts))
    t0 = time.perf_counter()
    short_case.run(dts[0])
    compile_short = time.perf_counter() - t0

    def ok_short(ys):
        return tip_error(short_case.tips(ys), ref[:n_short]) < 0.1

    k_stable = largest_stable_k(lambda k: short_case.run(SAVE_DT / k), ok_short)
    scan = []
    chosen = None
    t0 = time.perf_counter()
    case.run(SAVE_DT / k_stable)
    first_call = time.perf_counter() - t0
    for k in K_LADDER[K_LADDER.index(k_stable) :]:
        t0 = time.perf_counter()
        ys = case.run(SAVE_DT / k)
        wall = time.perf_counter() - t0
        err = tip_error(case.tips(ys), ref)
        scan.append({"dt": SAVE_DT / k, "tip_error": err, "wall_s": wall})
        print(f"    soromox dt {SAVE_DT / k:.3g}: err {err:.2e}, {wall:.2f} s")
        if err <= target:
            chosen = scan[-1]
            break
        if wall > budget_s:
            break
    row = {
        "code": "soromox",
        "case": "undamped, matched accuracy",
        "solver": "Tsit5, constant step (rollout_to default solver)",
        "n_dof": robot.num_coordinates,
        "modes": ALL_MODES,
        "order": order,
        "n_gauss": 10,
        "largest_stable_dt_short_span": SAVE_DT / k_stable,
        "stability_span_s": short,
        "scan": scan,
        "compile_s_short_span_first_call": compile_short,
    }
    if chosen is None:
        row["skipped"] = "target not reached within the dt ladder / budget"
        return row
    ts = timed_runs(lambda: case.run(chosen["dt"]), repeats, budget_s)
    row.update(summary(ts))
    row.update(
        {
            "settings": f"Tsit5, dt = {chosen['dt']:.3g} s",
            "dt": chosen["dt"],
            "tip_error": chosen["tip_error"],
            "first_call_s": first_call,
            "compile_s": max(0.0, first_call - statistics.median(ts)),
        }
    )
    return row


def bench_elastica_matched(ref, t1, target, repeats, budget_s, short):
    n_short = int(round(short / SAVE_DT)) + 1
    t0 = time.perf_counter()
    elastica_run(N_ELEMENTS_LADDER[0], SAVE_DT, K_LADDER[-1])  # numba JIT (or cache)
    jit_s = time.perf_counter() - t0
    scan, chosen = [], None
    for n in N_ELEMENTS_LADDER:
        k = largest_stable_k(
            lambda k, n=n: elastica_run(n, short, k)[0],
            lambda tips: tip_error(tips, ref[:n_short]) < 0.1,
        )
        # Confirm on the full span; step down the ladder if it goes unstable late.
        i = K_LADDER.index(k)
        while True:
            tips, wall, setup = elastica_run(n, t1, K_LADDER[i])
            err = tip_error(tips, ref)
            if err < 0.1 or i == len(K_LADDER) - 1:
                break
            i += 1
        k = K_LADDER[i]
        scan.append(
            {
                "n_elements": n,
                "dt": SAVE_DT / k,
                "tip_error": err,
                "wall_s": wall,
                "setup_s": setup,
            }
        )
        print(
            f"    pyelastica n {n}: largest stable dt {SAVE_DT / k:.3g}, "
            f"err {err:.2e}, {wall:.2f} s"
        )
        if err <= target:
            chosen = scan[-1]
            break
        if wall > budget_s:
            break
    row = {
        "code": "pyelastica",
        "case": "undamped, matched accuracy",
        "solver": "PositionVerlet, largest stable dt of the ladder",
        "stability_span_s": short,
        "scan": scan,
        "first_call_numba_jit_s": jit_s,
    }
    if chosen is None:
        row["skipped"] = "target not reached within the n_elements ladder / budget"
        return row
    n, dt = chosen["n_elements"], chosen["dt"]
    k = int(round(SAVE_DT / dt))
    ts = timed_runs(lambda: elastica_run(n, t1, k), repeats, budget_s)
    row.update(summary(ts))
    row.update(
        {
            "settings": f"PositionVerlet, {n} elements, dt = {dt:.3g} s",
            "n_elements": n,
            "dt": dt,
            "tip_error": chosen["tip_error"],
            "setup_s": chosen["setup_s"],
            "compile_s": jit_s,
        }
    )
    return row


# --------------------------------------------------------------------------- damped
def first_mode_decay_rate():
    """-Re(lambda) of the slowest oscillatory mode of the linearised damped rod."""
    rod = free_fall_rod(order=3, eta=ETA)
    n = rod.n_dof
    M = np.asarray(sorojax.mass_matrix(rod, jnp.zeros(n)))
    K = np.asarray(sorojax.stiffness_matrix(rod))
    D = np.asarray(sorojax.damping_matrix(rod))
    Minv = np.linalg.inv(M)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ K, -Minv @ D]])
    lam = np.linalg.eigvals(A)
    osc = lam[np.abs(lam.imag) > 1e-9]
    first = osc[np.argmin(np.abs(osc))]
    return float(-first.real), float(abs(first.imag))


def bench_damped(args, repeats, budget_s, elastica_choice):
    t1 = args.damped_span
    n_save = int(round(t1 / SAVE_DT)) + 1
    rows = []
    rod = free_fall_rod(order=3, eta=ETA)
    q0 = free_fall_q0(rod)
    case = SorojaxCase(rod, q0, t1, n_save, args.damped_solver)
    t0 = time.perf_counter()
    traj = case.run(args.damped_rtol, args.damped_atol)
    first_call = time.perf_counter() - t0
    ok = int(traj.result._value) == 0
    tips_sj = case.tips(traj)
    print(
        f"    sorojax damped: first call {first_call:.2f} s, "
        f"{int(traj.num_steps)} steps, success {ok}"
    )
    ts = timed_runs(
        lambda: case.run(args.damped_rtol, args.damped_atol), repeats, budget_s
    )
    row = {
        "code": "sorojax",
        "case": f"damped {t1:g} s (Kelvin-Voigt eta {ETA:g})",
        "settings": f"{args.damped_solver}, rtol {args.damped_rtol:g}, "
        f"atol {args.damped_atol:g}",
        "n_dof": rod.n_dof,
        "modes": BEND_TWIST,
        "order": 3,
        "steps": int(traj.num_steps),
        "success": ok,
        "first_call_s": first_call,
        **summary(ts),
        "tip_final_m": tips_sj[-1].tolist(),
    }
    row["compile_s"] = max(0.0, first_call - row["warm_median_s"])
    rows.append(row)
    sj_warm = row["warm_median_s"]

    if soromox is not None:
        robot, sq0 = soromox_robot(BEND_TWIST, 3, eta=ETA)
        dts = [SAVE_DT / k for k in K_LADDER]
        short = min(args.stability_span, t1)
        n_short = int(round(short / SAVE_DT)) + 1
        short_case = SoromoxCase(robot, sq0, short, n_short, min(dts))
        k = largest_stable_k(
            lambda k: short_case.run(SAVE_DT / k),
            lambda ys: tip_error(short_case.tips(ys), tips_sj[:n_short]) < 0.1,
        )
        smx = SoromoxCase(robot, sq0, t1, n_save, min(dts))
        i = K_LADDER.index(k)
        while True:
            t0 = time.perf_counter()
            ys = smx.run(SAVE_DT / K_LADDER[i])
            first = time.perf_counter() - t0
            agree = tip_error(smx.tips(ys), tips_sj)
            if agree < 0.1 or i == len(K_LADDER) - 1:
                break
            i += 1
        dt = SAVE_DT / K_LADDER[i]
        ts = timed_runs(lambda dt=dt: smx.run(dt), repeats, budget_s)
        srow = {
            "code": "soromox",
            "case": row["case"],
            "settings": f"Tsit5, largest stable dt = {dt:.3g} s",
            "n_dof": robot.num_coordinates,
            "modes": BEND_TWIST,
            "order": 3,
            "n_gauss": 10,
            "dt": dt,
            "first_call_s": first,
            **summary(ts),
            "tip_difference_vs_sorojax_damped": agree,
        }
        srow["compile_s"] = max(0.0, first - srow["warm_median_s"])
        srow["ratio_vs_sorojax"] = srow["warm_median_s"] / sj_warm
        print(f"    soromox damped: dt {dt:.3g}, warm {srow['warm_median_s']:.2f} s")
        rows.append(srow)

    if elastica is not None and elastica_choice is not None:
        sigma1, omega1 = first_mode_decay_rate()
        gamma = 2.0 * sigma1
        n, dt = elastica_choice["n_elements"], elastica_choice["dt"]
        k = int(round(SAVE_DT / dt))
        tips, first, setup = elastica_run(n, t1, k, damping=gamma)
        ts = timed_runs(
            lambda: elastica_run(n, t1, k, damping=gamma), repeats, budget_s
        )
        erow = {
            "code": "pyelastica",
            "case": f"damped {t1:g} s (AnalyticalLinearDamper, uniform)",
            "settings": f"PositionVerlet, {n} elements, dt = {dt:.3g} s, "
            f"uniform_damping_constant {gamma:.3g} 1/s",
            "n_elements": n,
            "dt": dt,
            "uniform_damping_constant": gamma,
            "fitted_to": f"first-mode decay rate {sigma1:.4g} 1/s "
            f"(omega {omega1:.4g} rad/s) of the Kelvin-Voigt rod",
            "setup_s": setup,
            **summary(ts),
            "tip_difference_vs_sorojax_damped_info_only": tip_error(tips, tips_sj),
        }
        erow["ratio_vs_sorojax"] = erow["warm_median_s"] / sj_warm
        print(f"    pyelastica damped: warm {erow['warm_median_s']:.2f} s")
        rows.append(erow)
    return rows


# --------------------------------------------------------------------------- main
def environment():
    env = base_environment(
        soromox_version=getattr(soromox, "__version__", None),
        soromox_import_error=SOROMOX_IMPORT_ERROR,
        pyelastica_version=None,
        pyelastica_import_error=ELASTICA_IMPORT_ERROR,
        executable=sys.executable,
    )
    try:
        from importlib.metadata import version

        env["pyelastica_version"] = version("pyelastica")
        env["numba_version"] = version("numba")
    except Exception:  # noqa: BLE001
        pass
    return env


def fmt_s(x):
    return "-" if x is None else (f"{x:.3f} s" if x < 10 else f"{x:.1f} s")


def print_table(rows):
    print(
        f"\n{'code':<11}{'case':<30}{'settings':<54}{'size':>10}{'compile':>10}"
        f"{'warm med':>11}{'runs':>5}{'tip err':>10}"
    )
    for r in rows:
        size = f"{r['n_dof']} dof" if "n_dof" in r else f"{r.get('n_elements', '-')} el"
        if "skipped" in r:
            print(f"{r['code']:<11}{r['case'][:29]:<30}skipped: {r['skipped']}")
            continue
        err = r.get("tip_error")
        if err is None:
            err = r.get("tip_difference_vs_sorojax_damped")
        err_s = "-" if err is None else f"{err:.1e}"
        comp = r.get("compile_s")
        print(
            f"{r['code']:<11}{r['case'][:29]:<30}{r['settings'][:53]:<54}{size:>10}"
            f"{fmt_s(comp):>10}{fmt_s(r['warm_median_s']):>11}{r['repeats']:>5}"
            f"{err_s:>10}"
        )


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--quick",
        action="store_true",
        help="short spans (0.3 s matched, 1 s damped), 1 timed run",
    )
    ap.add_argument(
        "--target",
        type=float,
        default=1e-2,
        help="tip error / L (1e-2: the undamped shearable rod converges slowly, its"
        " order-6 reference is itself a few 1e-3 L from the continuum)",
    )
    ap.add_argument("--span", type=float, default=None, help="matched span [s] (1)")
    ap.add_argument("--damped-span", type=float, default=None, help="[s] (5)")
    defaults = inspect.signature(sorojax.simulate).parameters
    ap.add_argument("--damped-solver", default="auto", help="default: simulate's")
    ap.add_argument("--damped-rtol", type=float, default=defaults["rtol"].default)
    ap.add_argument("--damped-atol", type=float, default=defaults["atol"].default)
    ap.add_argument(
        "--solvers",
        default="ros34pw2,tsit5,rosenbrock_trapezoid",
        help="sorojax solvers for the matched-accuracy runs (comma separated)",
    )
    ap.add_argument("--repeats", type=int, default=None, help="timed runs (5)")
    ap.add_argument(
        "--budget",
        type=float,
        default=600.0,
        help="seconds: skip a sorojax solver whose run is estimated above this, and "
        "stop repeating a timed run once its repeats took this long",
    )
    ap.add_argument("--stability-span", type=float, default=0.3)
    ap.add_argument("--recompute-reference", action="store_true")
    ap.add_argument(
        "--skip", default="", help="comma list of: matched,soromox,pyelastica,damped"
    )
    args = ap.parse_args(argv)
    span = args.span or (0.3 if args.quick else 1.0)
    args.damped_span = args.damped_span or (1.0 if args.quick else 5.0)
    repeats = args.repeats or (1 if args.quick else 5)
    skip = set(filter(None, args.skip.split(",")))
    n_save = int(round(span / SAVE_DT)) + 1
    solvers = [s for s in args.solvers.split(",") if s]

    env = environment()
    print(
        f"jax {env['jax_version']}, soromox {env['soromox_version']}, pyelastica "
        f"{env['pyelastica_version']} on {env['devices']}, {env['cpu_count']} CPUs, "
        f"load average {env['load_average_at_start'][0]:.1f}"
    )
    t_start = time.perf_counter()

    print(f"\n[1] Reference (sorojax, undamped, all six strain modes, {span:g} s)")
    cache = RESULTS_DIR / (
        "peers_reference.npz" if span == 1.0 else f"peers_reference_{span:g}s.npz"
    )
    ref, ref_meta = sorojax_reference(span, n_save, cache, args.recompute_reference)
    for name, r in ref_meta["runs"].items():
        print(f"    {name:<58} |tip - ref|/L <= {r['tip_difference_vs_reference']:.1e}")

    matched = []
    short = min(args.stability_span, span)
    order = matched_order(ref_meta, args.target)
    if "matched" not in skip:
        print(f"\n[2] Matched tip accuracy <= {args.target:g} L, undamped, {span:g} s")
        if order is None:
            print(f"    no order in {MATCHED_ORDERS} reaches the target: skipped")
        else:
            print(f"    sorojax model: all six strains, order {order}")
            matched = bench_sorojax_matched(
                ref, span, n_save, args.target, solvers, repeats, args.budget, order
            )
    if soromox is not None and order is not None and not {"soromox", "matched"} & skip:
        matched.append(
            bench_soromox_matched(
                ref, span, n_save, args.target, repeats, args.budget, short, order
            )
        )
    elastica_row = None
    if elastica is not None and not {"pyelastica", "matched"} & skip:
        elastica_row = bench_elastica_matched(
            ref, span, args.target, repeats, args.budget, short
        )
        matched.append(elastica_row)
    # Also the bend/twist (inextensible, shearless) rod: its model error vs the
    # reference, at a tight tolerance (information).
    rod3, q3 = sorojax_rod(BEND_TWIST, 3)
    c3 = SorojaxCase(rod3, q3, span, n_save, "dopri8", max_steps=10**6)
    err3 = tip_error(c3.tips(c3.run(1e-10, 1e-10)), ref)
    print(
        f"    model effect: sorojax modes (1,1,1,0,0,0) order 3 (12 DoF, no stretch/"
        f"shear) vs the reference: {err3:.1e} L"
    )

    damped = []
    if "damped" not in skip:
        print(f"\n[3] Speed, damped {args.damped_span:g} s")
        el_choice = (
            elastica_row if elastica_row and "skipped" not in elastica_row else None
        )
        damped = bench_damped(args, repeats, args.budget, el_choice)

    rows = matched + damped
    print_table(rows)

    def base(case_rows):
        ok = [r for r in case_rows if r["code"] == "sorojax" and "skipped" not in r]
        return ok

    ratios = {}
    sj_matched = base(matched)
    for r in matched:
        if r["code"] == "sorojax" or "skipped" in r:
            continue
        for s in sj_matched:
            ratios[f"matched: {r['code']} / sorojax {s['solver']}"] = (
                r["warm_median_s"] / s["warm_median_s"]
            )
    sj_damped = base(damped)
    for r in damped:
        if r["code"] == "sorojax":
            continue
        for s in sj_damped:
            ratios[f"damped: {r['code']} / sorojax"] = (
                r["warm_median_s"] / s["warm_median_s"]
            )
    for s in sj_damped:
        ratios["damped: SoRoSim 1.5 s (MATLAB, ode15s) / sorojax"] = (
            SOROSIM_DAMPED_S / s["warm_median_s"]
        )
    print("\nRatios (peer warm time / sorojax warm time; > 1: sorojax faster)")
    for k, v in ratios.items():
        print(f"    {k:<55} {v:8.2f}")
    for s in sj_damped:
        met = s["warm_median_s"] < TARGET_DAMPED_S
        print(
            f"    target: sorojax damped {args.damped_span:g} s warm < 0.15 s: "
            f"{'met' if met else 'NOT met'} ({s['warm_median_s']:.3f} s)"
        )

    total = time.perf_counter() - t_start
    print(f"\nTotal benchmark time {total:.0f} s")
    out = {
        "environment": env,
        "settings": {
            "quick": args.quick,
            "target_tip_error_over_L": args.target,
            "matched_span_s": span,
            "damped_span_s": args.damped_span,
            "save_dt_s": SAVE_DT,
            "repeats": repeats,
            "budget_s": args.budget,
            "stability_span_s": short,
            "rod": {
                "L": L,
                "r_base": R_BASE,
                "r_tip": R_TIP,
                "E": E,
                "G": G,
                "rho": RHO,
                "eta_damped": ETA,
                "kappa0": KAPPA0,
                "gravity": GRAVITY,
            },
        },
        "reference": ref_meta,
        "bend_twist_model_error_vs_reference": err3,
        "matched_accuracy": matched,
        "damped": damped,
        "ratios": ratios,
        "total_benchmark_s": total,
        "load_average_at_end": list(os.getloadavg()),
    }
    RESULTS_DIR.mkdir(parents=True, exist_ok=True)
    name = "peers_quick.json" if args.quick else "peers.json"
    path = RESULTS_DIR / name
    path.write_text(json.dumps(out, indent=2, default=lambda o: list(o)))
    print(f"Wrote {path}")


if __name__ == "__main__":
    main()
