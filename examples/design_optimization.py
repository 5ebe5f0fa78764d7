"""Gradient-based design of a tendon-driven soft arm, through its statics solves.

What this example teaches:

- how to put design variables into a model's array leaves (``eqx.tree_at``), so
  that one compiled program serves every design;
- how to differentiate equilibria with respect to the design: ``jax.jacfwd``
  through ``jax.vmap`` of ``sorojax.solve_statics`` (implicit function theorem,
  no finite differences);
- how to drive optimistix's Levenberg-Marquardt one step at a time (to warm-start
  the solves and record progress), and scipy's optimisers with the same programs.

The arm: 0.9 m hanging along world -z under gravity, two soft links of one division
each (0.4 m + 0.5 m, so that each has its own Young's modulus), circular radius
linear within each link between a base, a middle and a tip radius, density 1000
kg/m^3, bending about local y and z at Legendre order 1 (4 DoF per link, 8 in all;
inextensible, shearless, no torsion). Four cables at 90 degree spacing (local +y,
+z, -y, -z; local y is world +y and local z world +x) run base to tip inside the
body; a cable's offset is a fraction of the local radius, that fraction linear along
the arm from its base value to its tip value, and the path is linear within each
link between the offsets at base, middle and tip.

Design variables (13, each between physical bounds, :data:`LOWER`, :data:`UPPER`):
the base and tip offset fractions of the four cables (0.3-0.9 of the radius), the
base, middle and tip radii, and E of each link (0.5-2 MPa). The optimisers work on
unconstrained z with theta = lo + (hi - lo) sigmoid(z) (for E on log E), so every
iterate is a buildable arm.

The task: for 8 tension sets (each cable alone at 4 N, each adjacent pair at 3 N
each) the tip must reach the tips of a hidden reference design
(:data:`REFERENCE`), starting from the library's arm (:data:`INITIAL`); the optimum
is 0. Objective: the mean squared tip distance [mm^2] over the 8 sets.

Every evaluation solves the 8 statics at once (``jax.vmap`` over
``sorojax.solve_statics``, ``throw=False``, result codes checked, each solve
warm-started from the last evaluation's equilibria). Optimisers, from the same
start:

- Levenberg-Marquardt (``optimistix.IndirectLevenbergMarquardt``) on the 24 tip
  residuals [mm], its Jacobian by forward mode through the solves (the program
  L-BFGS-B uses);
- scipy's L-BFGS-B on the objective with its gradient from ``jax.jacfwd``;
- scipy's Nelder-Mead (derivative-free) for comparison.

A solve is one statics solve of one tension set (SoRoSim's count: its published
design study took 2887 solves, 93 s, with MATLAB's patternsearch on its own
problem); seconds are wall time with the programs already compiled. The found
design fits the tips, not the reference's every value: E and the radii trade off
(the problem is sloppy).

What to expect (``python examples/design_optimization.py``, 2-core CPU):
Levenberg-Marquardt reaches J <= 1e-2 mm^2 (tip RMS 0.1 mm) after 136 solves and
9.4e-7 mm^2 (tip RMS 1 um) after 256 solves (32 evaluations, 0.3 s); L-BFGS-B needs
456 solves to reach 1e-2 mm^2, Nelder-Mead 7088 (3.8 s), and Nelder-Mead ends at
6.6e-5 mm^2 after its 2000 evaluations (16000 solves, 7.6 s), a level
Levenberg-Marquardt passes after 136 solves. The first run takes about 25 s in all,
most of it tracing and compiling the programs (value; residuals and Jacobian; the
Levenberg-Marquardt step, which takes the residuals and Jacobian as inputs and
holds no solves of its own); later runs load them from the persistent compilation
cache.

Run::

    python examples/design_optimization.py [--nm-evals 2000] [--lbfgs-evals 200]
        [--lm-evals 40] [--out DIR] [--overwrite]

(the test runs ``--nm-evals 200 --lbfgs-evals 30``).
"""

import argparse
import functools
import pathlib
import time

import jax

jax.config.update("jax_enable_x64", True)

import equinox as eqx  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import matplotlib  # noqa: E402
import numpy as np  # noqa: E402
import optimistix as optx  # noqa: E402
import scipy.optimize  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import sorojax as sj  # noqa: E402

sj.set_runtime_flags()  # XLA's CPU runtime flags: before any JAX array exists

LENGTHS = (0.4, 0.5)  # link lengths [m]
X_MID = LENGTHS[0] / sum(LENGTHS)  # arm-normalised position of the middle
DIRECTIONS = ((1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0))
CABLE_NAMES = ("+y", "+z", "-y", "-z")
TENSIONS = np.array(
    [[4.0, 0, 0, 0], [0, 4.0, 0, 0], [0, 0, 4.0, 0], [0, 0, 0, 4.0]]
    + [[3.0, 3.0, 0, 0], [0, 3.0, 3.0, 0], [0, 0, 3.0, 3.0], [3.0, 0, 0, 3.0]]
)
"""Tension sets [N] of cables (+y, +z, -y, -z): singles at 4 N, adjacent pairs."""

NAMES = (
    *(f"f_base {c}" for c in CABLE_NAMES),
    *(f"f_tip {c}" for c in CABLE_NAMES),
    "r_base",
    "r_mid",
    "r_tip",
    "E_1",
    "E_2",
)
"""Design variables: offset fractions (of the local radius), radii [m], E [Pa]."""
LOWER = np.array([0.3] * 8 + [0.015, 0.010, 0.006, 0.5e6, 0.5e6])
UPPER = np.array([0.9] * 8 + [0.025, 0.020, 0.014, 2.0e6, 2.0e6])
LOG = np.array([False] * 11 + [True] * 2)  # mapped on log scale
INITIAL = np.array([0.75] * 8 + [0.02, 0.02 - 0.01 * X_MID, 0.01, 1e6, 1e6])
"""Start: ``sorojax._mechanisms.cable_manipulator``'s arm (linear taper 2 -> 1 cm)."""
REFERENCE = np.array(
    [0.6, 0.8, 0.85, 0.5, 0.5, 0.7, 0.6, 0.85, 0.022, 0.013, 0.008, 1.4e6, 0.7e6]
)
"""The hidden design whose tips are the targets."""


# ------------------------------------------------------------------ the model
def _hanging() -> np.ndarray:
    """Rotation by +90 degrees about y: local x (the rod axis) -> world -z."""
    g = np.eye(4)
    g[:3, :3] = [[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]]
    return g


def build_arm(design=INITIAL) -> sj.Linkage:
    """The arm at a physical ``design`` (13 values in :data:`NAMES` order)."""
    d = np.asarray(design, dtype=float)
    r = d[8:11]
    basis = sj.LegendreBasis((0, 1, 1, 0, 0, 0), 1)
    links = [
        sj.SoftLink(
            [sj.Division(LENGTHS[i], sj.CircularSection((r[i], r[i + 1])), basis)],
            sj.Material(E=d[11 + i], poisson=0.5, rho=1000.0),
            color="tab:orange",
        )
        for i in range(2)
    ]
    cables = []
    for k, ((c, s), name) in enumerate(zip(DIRECTIONS, CABLE_NAMES, strict=True)):
        off = _offsets(d[k], d[4 + k], r)
        spans = [
            sj.CableSpan(
                i + 1,
                sj.ObliquePath(
                    (off[i] * c, off[i] * s), (off[i + 1] * c, off[i + 1] * s)
                ),
            )
            for i in range(2)
        ]
        cables.append(sj.Cable(spans, name=name))
    return sj.Linkage(
        links,
        placements=jnp.asarray(np.stack([_hanging(), np.eye(4)])),
        gravity=(0.0, 0.0, -9.81),
        actuators=cables,
    )


def _offsets(f_base, f_tip, r):
    """Cable offsets [m] at base, middle, tip: fraction linear along the arm."""
    f_mid = f_base + (f_tip - f_base) * X_MID
    return (f_base * r[0], f_mid * r[1], f_tip * r[2])


def _design_nodes(arm: sj.Linkage) -> list:
    """The array leaves a design sets, in :func:`_design_values` order."""
    nodes = []
    for link in arm.links:
        prof = link.divisions[0].section.radius
        nodes += [prof.start, prof.end, link.material.E]
    for cable in arm.actuators:
        for span in cable.route:
            nodes += [span.path.start, span.path.end]
    return nodes


def _design_values(design) -> list:
    """Leaf values of the 13 physical ``design`` values, as :func:`_design_nodes`."""
    r = design[8:11]
    values = []
    for i in range(2):
        values += [r[i], r[i + 1], design[11 + i]]
    for k, (c, s) in enumerate(DIRECTIONS):
        off = _offsets(design[k], design[4 + k], r)
        direction = jnp.array([c, s])
        for i in range(2):
            values += [off[i] * direction, off[i + 1] * direction]
    return values


def with_design(arm: sj.Linkage, design) -> sj.Linkage:
    """``arm`` with the 13 physical values of ``design`` in its array leaves.

    Only array leaves change (``eqx.tree_at``): the structure, hence the compiled
    program, stays the same for every design.
    """
    return eqx.tree_at(_design_nodes, arm, _design_values(design))


def design_of(z):
    """Physical design from the unconstrained z (sigmoid between the bounds)."""
    s = jax.nn.sigmoid(z)
    lin = LOWER + (UPPER - LOWER) * s
    log = jnp.exp(np.log(LOWER) + (np.log(UPPER) - np.log(LOWER)) * s)
    return jnp.where(LOG, log, lin)


def z_of(design) -> np.ndarray:
    """Inverse of :func:`design_of`."""
    d = np.asarray(design, dtype=float)
    lo, hi = np.where(LOG, np.log(LOWER), LOWER), np.where(LOG, np.log(UPPER), UPPER)
    s = (np.where(LOG, np.log(d), d) - lo) / (hi - lo)
    return np.log(s / (1 - s))


def tips(arm, design, q0):
    """Equilibrium tips (8, 3) [m], coordinates (8, n_dof) and success flags (8,)."""
    lk = with_design(arm, design)

    def one(u, q_start):
        # the warm start is a guess: no derivative flows through it
        q_start = jax.lax.stop_gradient(q_start)
        sol = sj.solve_statics(lk, q_start, u, throw=False)
        ok = sol.result == sj.RESULTS.successful
        return sj.tip_pose(lk, sol.q)[:3, 3], sol.q, ok

    return jax.vmap(one)(jnp.asarray(TENSIONS), q0)


def _residuals(z, arm, targets, q0):
    p, q, ok = tips(arm, design_of(z), q0)
    r = 1e3 * (p - targets).reshape(-1)  # [mm]
    return r, (r, p, q, ok)


def _evaluate(z, arm, targets, q0):
    r, (_, p, q, ok) = _residuals(z, arm, targets, q0)
    return jnp.mean(jnp.sum(r.reshape(-1, 3) ** 2, axis=1)), p, q, ok


def _residuals_and_jacobian(z, arm, targets, q0):
    jac, (r, _, q, ok) = jax.jacfwd(_residuals, has_aux=True)(z, arm, targets, q0)
    return r, jac, q, ok


# Levenberg-Marquardt as a trust-region method: each step fits the damping mu of
# (J^T J + mu I) dz = -J^T r to a trust radius on dz, grown or shrunk by how well the
# linear model predicted the decrease. This problem is sloppy (the Jacobian's
# singular values run from 1e2 down to 1e-5 at the reference): bounding the step's
# length, as this variant does, keeps the first steps from running along the weak
# directions to the bounds, where the sigmoid flattens. (optx.LevenbergMarquardt,
# which updates mu directly, reaches 2e-4 mm^2 in 40 steps here; this one 1e-6.)
# The loop below stops on the objective; the solver's own Cauchy termination
# (change of z and of the residuals) only at 1e-12.
LM = optx.IndirectLevenbergMarquardt(rtol=1e-12, atol=1e-12)


def _evaluated(r, jac, aux, z_eval):
    """The tip residuals as one step of the solver sees them.

    A Gauss-Newton step of optimistix evaluates its function once, with the
    Jacobian, at the trial point ``state.y_eval``. Given the residuals ``r`` and
    Jacobian ``jac`` there (from ``residuals_and_jacobian``, the program L-BFGS-B
    uses too), the affine map ``r + jac (z - z_eval)`` has that value and that
    Jacobian at ``z_eval``: the step then needs no statics solves of its own, so
    its program is small and the solves are compiled once.
    """

    def fn(z, args):
        return r + jac @ (z - z_eval), aux

    return fn


def _lm_init(z, r, jac, aux):
    fn = _evaluated(r, jac, aux, z)
    f_struct, aux_struct = jax.eval_shape(fn, z, None)
    return LM.init(fn, z, None, {}, f_struct, aux_struct, frozenset())


def _placeholders(n, n_z, q):
    """Zeros shaped as ``residuals_and_jacobian``'s ``(r, jac, aux)``.

    For ``n`` solves of ``q``'s shape and ``n_z`` design variables: what
    ``lm_init`` reads (shapes only).
    """
    return jnp.zeros(3 * n), jnp.zeros((3 * n, n_z)), (q, jnp.ones(n, dtype=bool))


def _lm_step(z, state, r, jac, aux):
    fn = _evaluated(r, jac, aux, state.y_eval)
    z, state, _ = LM.step(fn, z, None, {}, state, frozenset())
    done, result = LM.terminate(fn, z, None, {}, state, frozenset())
    return z, state, done, result


@functools.cache
def programs():
    """``(evaluate, residuals_and_jacobian, lm_init, lm_step)``: jitted programs.

    ``evaluate(z, arm, targets, q0)`` -> (objective [mm^2], tips (8, 3) [m],
    equilibria (8, n_dof), success flags (8,)): the value-only program (Nelder-Mead,
    targets, figures). ``residuals_and_jacobian(z, arm, targets, q0)`` -> (residuals
    (24,) [mm], Jacobian (24, 13) in z, equilibria, success flags): ``jax.jacfwd``
    through the solves, i.e. linear solves with the converged equilibria's tangent
    stiffness (implicit function theorem), no further Newton iterations. ``q0``
    warm-starts the 8 solves. Both are ``sorojax.jit`` programs at XLA's default
    level (``tiered=False``: the optimisers call them hundreds of times), so that
    ``sorojax.prepare`` can compile the Jacobian's in a worker thread while the
    value program compiles and runs. ``lm_init(z, r, jac, aux)`` and
    ``lm_step(z, state, r, jac, aux)`` are one Levenberg-Marquardt step of
    optimistix, stepped from Python: given the residuals, Jacobian and ``aux =
    (equilibria, success flags)`` at the solver's trial point ``state.y_eval``
    (from ``residuals_and_jacobian``; ``lm_init`` reads only their shapes), the
    step accepts or rejects that point and returns ``(z, state, done, result)``.
    """
    return (
        sj.jit(_evaluate, tiered=False),
        sj.jit(_residuals_and_jacobian, tiered=False),
        sj.jit(_lm_init, tiered=False),
        sj.jit(_lm_step, tiered=False),
    )


class Problem:
    """Counts solves, times and warm-starts the evaluations of one optimisation.

    Each call solves the 8 tension sets (8 solves) from the last call's equilibria;
    the history holds (solves so far, objective, seconds so far) per call.
    """

    def __init__(self, arm, targets):
        self.arm, self.targets = arm, jnp.asarray(targets)
        self.n = len(TENSIONS)
        self.reset()

    def reset(self):
        """Start over: cold start, empty history, clock at zero."""
        self.q = jnp.zeros((self.n, self.arm.n_dof))
        self.history, self.failed = [], 0
        self.t0 = time.perf_counter()

    def record(self, J, q, ok):
        """Append one evaluation (objective J, equilibria q, success flags ok)."""
        if bool(np.all(np.asarray(ok))):  # a failed solve is no warm start
            self.q = q
        else:
            self.failed += 1
            J = np.inf
        solves = (self.history[-1][0] if self.history else 0) + self.n
        self.history.append((solves, float(J), time.perf_counter() - self.t0))
        return float(J)

    def value(self, z):
        """Objective [mm^2] (inf where a solve failed)."""
        J, _, q, ok = programs()[0](jnp.asarray(z), self.arm, self.targets, self.q)
        return self.record(J, q, ok)

    def residuals(self, z):
        """Residuals (24,) [mm] and their Jacobian (24, 13), None where failed."""
        r, jac, q, ok = programs()[1](jnp.asarray(z), self.arm, self.targets, self.q)
        r, jac = np.asarray(r), np.asarray(jac)
        J = self.record(np.sum(r**2) / self.n, q, ok)
        return (r, jac) if np.isfinite(J) else (None, None)


# --------------------------------------------------------------- optimisers
def levenberg_marquardt(problem, z0, max_evals=40, J_tol=1e-6):
    """Optimistix's Levenberg-Marquardt on the tip residuals, one step at a time.

    Stepping the solver from Python (``init``/``step``/``terminate``) rather than
    calling ``optx.least_squares`` lets each step warm-start its 8 solves from the
    last accepted equilibria and record the objective, the solves and the time.
    Every step is one evaluation (8 solves, with the Jacobian, at the solver's
    trial point), accepted or not; stops when J <= ``J_tol`` mm^2, when the solver
    converges or after ``max_evals`` evaluations.
    """
    _, residuals_and_jacobian, lm_init, lm_step = programs()
    z = jnp.asarray(z0, dtype=float)
    state = lm_init(z, *_placeholders(problem.n, z.size, problem.q))
    for _ in range(max_evals):
        r, jac, q, ok = residuals_and_jacobian(
            state.y_eval, problem.arm, problem.targets, problem.q
        )
        z, state, done, result = lm_step(z, state, r, jac, (q, ok))
        r = state.f_info.residual  # at the last accepted point
        q, ok = state.aux
        J = problem.record(jnp.sum(r**2) / problem.n, q, ok)
        if J <= J_tol or bool(done):
            break
    if result != optx.RESULTS.successful:
        raise RuntimeError(f"Levenberg-Marquardt failed: {result}")
    return np.asarray(z)


def lbfgs(problem, z0, max_evals=200):
    """Scipy's L-BFGS-B on the objective, gradient 2 J^T r / n from the same program."""

    def fun(z):
        r, jac = problem.residuals(z)
        if r is None:
            return np.inf, np.zeros_like(z)
        return np.sum(r**2) / problem.n, 2 * jac.T @ r / problem.n

    opts = {"maxfun": max_evals, "maxiter": max_evals, "ftol": 1e-15, "gtol": 1e-10}
    return scipy.optimize.minimize(fun, z0, jac=True, method="L-BFGS-B", options=opts).x


def nelder_mead(problem, z0, max_evals=2000, step=0.5):
    """Scipy's Nelder-Mead (adaptive parameters for 13 dimensions), same start.

    The initial simplex steps ``step`` in each z (about 12 % of a variable's range;
    scipy's default 5 % of z is a near-zero simplex where z = 0).
    """
    simplex = z0 + np.vstack([np.zeros(len(z0)), step * np.eye(len(z0))])
    opts = {
        "maxfev": max_evals,
        "initial_simplex": simplex,
        "adaptive": True,
        "xatol": 1e-10,
        "fatol": 1e-14,
    }
    return scipy.optimize.minimize(
        problem.value, z0, method="Nelder-Mead", options=opts
    ).x


def reach(history, J):
    """(solves, seconds) at the first evaluation with objective <= J, or None."""
    for solves, value, t in history:
        if value <= J:
            return int(solves), float(t)
    return None


# ------------------------------------------------------------------------ main
def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lm-evals", type=int, default=40, help="LM evaluation budget")
    ap.add_argument("--lbfgs-evals", type=int, default=200, help="L-BFGS-B budget")
    ap.add_argument("--nm-evals", type=int, default=2000, help="Nelder-Mead budget")
    ap.add_argument("--out", default=".", help="folder for the PNG")
    ap.add_argument("--overwrite", action="store_true", help="replace an old PNG")
    args = ap.parse_args(argv)
    sj.enable_compilation_cache()  # later runs load the compiled programs
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    path = out / "design_optimization.png"
    if path.exists() and not args.overwrite:
        raise SystemExit(f"{path} exists; pass --overwrite to replace it")

    arm = build_arm(INITIAL)
    n, n_dof = len(TENSIONS), arm.n_dof
    print(f"arm: {n_dof} DoF, {len(NAMES)} design variables, {n} tension sets")
    q_cold = jnp.zeros((n, n_dof))
    z0 = z_of(INITIAL)
    evaluate, residuals_and_jacobian, lm_init, lm_step = programs()
    # first calls: trace + compile (or load from the cache) + run. The programs
    # with Jacobians (for L-BFGS-B and for Levenberg-Marquardt's step) are traced
    # here and compiled in worker threads meanwhile; their first calls wait for
    # what is left of those compiles.
    cold = {}
    t = time.perf_counter()
    zeros = jnp.zeros((n, 3))
    sj.prepare(residuals_and_jacobian, jnp.asarray(z0), arm, zeros, q_cold)
    placeholders = _placeholders(n, len(z0), q_cold)  # shapes as the optimisation's
    lm_state = lm_init(jnp.asarray(z0), *placeholders)
    lm_ready = sj.prepare(lm_step, jnp.asarray(z0), lm_state, *placeholders)
    # the targets: the reference design's tips (the value program, any targets)
    _, targets, _, ok = evaluate(jnp.asarray(z_of(REFERENCE)), arm, zeros, q_cold)
    ok = np.asarray(ok)  # waits for the result
    cold["value"] = time.perf_counter() - t
    if not ok.all():
        raise RuntimeError(f"reference solves failed: success flags {ok}")
    t = time.perf_counter()
    jax.block_until_ready(residuals_and_jacobian(jnp.asarray(z0), arm, targets, q_cold))
    cold["jacobian"] = time.perf_counter() - t
    t = time.perf_counter()
    if lm_ready is not None:
        lm_ready.result()  # the rest of the step's compile
    cold["lm_step"] = time.perf_counter() - t
    print(
        "first calls (trace + compile + run): value (after tracing the Jacobian "
        f"programs) {cold['value']:.1f} s, then waiting for the compiles in worker "
        f"threads: residuals + Jacobian {cold['jacobian']:.1f} s, Levenberg-Marquardt "
        f"step {cold['lm_step']:.1f} s"
    )

    problem = Problem(arm, targets)
    runs = {}
    for method, run, budget in (
        ("Levenberg-Marquardt", levenberg_marquardt, args.lm_evals),
        ("L-BFGS-B", lbfgs, args.lbfgs_evals),
        ("Nelder-Mead", nelder_mead, args.nm_evals),
    ):
        problem.reset()
        z = run(problem, z0, budget)
        hist = np.array(problem.history)
        best = int(np.argmin(hist[:, 1]))
        runs[method] = {
            "history": hist,
            "z": z,
            "design": np.asarray(design_of(jnp.asarray(z))),
            "J0": float(hist[0, 1]),
            "J": float(hist[best, 1]),
            "solves": int(hist[-1, 0]),
            "seconds": float(hist[-1, 2]),
            "failed": problem.failed,
        }
        r = runs[method]
        print(
            f"{method}: J {r['J0']:.4g} -> {r['J']:.3g} mm^2 (tip RMS "
            f"{np.sqrt(r['J']) * 1e3:.3g} um) in {len(hist)} evaluations, "
            f"{r['solves']} solves, {r['seconds']:.2f} s; failed evaluations "
            f"{r['failed']}"
        )
    lm, nm = runs["Levenberg-Marquardt"], runs["Nelder-Mead"]
    # the same objective for every method: what Nelder-Mead reached in its budget
    common = max(nm["J"], lm["J"])
    for r in runs.values():
        r["to_common"] = reach(r["history"], common)
    print(f"to reach J <= {common:.3g} mm^2 (Nelder-Mead's best in its budget):")
    for method, r in runs.items():
        got = r["to_common"]
        msg = "not reached" if got is None else f"{got[0]} solves, {got[1]:.2f} s"
        print(f"  {method}: {msg}")
    for J in (1.0, 1e-2, 1e-6):
        got = {m: reach(r["history"], J) for m, r in runs.items()}
        print(
            f"to reach J <= {J:g} mm^2: "
            + "; ".join(
                f"{m} "
                + ("not reached" if g is None else f"{g[0]} solves, {g[1]:.2f} s")
                for m, g in got.items()
            )
        )
    err = np.abs(lm["design"] - REFERENCE) / (UPPER - LOWER)
    print(f"LM design vs reference: largest error {err.max():.2e} of a range")

    p0 = np.asarray(evaluate(jnp.asarray(z0), arm, targets, q_cold)[1])
    p1 = np.asarray(evaluate(jnp.asarray(lm["z"]), arm, targets, q_cold)[1])
    _plot(runs, np.asarray(targets), p0, p1, path)
    print(f"wrote {path}")
    return {
        "runs": runs,
        "targets": np.asarray(targets),
        "tips_initial": p0,
        "tips_final": p1,
        "common_J": common,
        "cold_seconds": cold,
        "arm": arm,
        "z0": z0,
    }


def _plot(runs, targets, p0, p1, path):
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.6))
    ax = axes[0]
    for (method, r), style in zip(runs.items(), ("o-", "s-", "-"), strict=True):
        h = r["history"]
        ax.loglog(h[:, 0], np.minimum.accumulate(h[:, 1]), style, ms=3, label=method)
    ax.axvline(2887, color="k", ls=":", lw=1, label="SoRoSim patternsearch (2887)")
    ax.set_ylim(1e-10, 1e5)
    ax.set_xlabel("statics solves (one per tension set and evaluation)")
    ax.set_ylabel("best mean squared tip error [mm^2]")
    ax.set_title("objective vs solves")
    ax.legend(fontsize=8, loc="lower right")
    ax.grid(alpha=0.3, which="both")

    ax = axes[1]
    ax.plot(targets[:, 0] * 1e3, targets[:, 1] * 1e3, "r*", ms=12, label="targets")
    ax.plot(p0[:, 0] * 1e3, p0[:, 1] * 1e3, "o", mfc="none", label="initial design")
    ax.plot(p1[:, 0] * 1e3, p1[:, 1] * 1e3, "k.", label="optimised (LM)")
    for a, b in zip(p0, targets, strict=True):
        ax.plot([a[0] * 1e3, b[0] * 1e3], [a[1] * 1e3, b[1] * 1e3], "c-", lw=0.6)
    ax.plot(0, 0, "k+")
    ax.set_aspect("equal")
    ax.set_xlabel("tip x [mm]")
    ax.set_ylabel("tip y [mm]")
    ax.set_title("tips, seen from above (8 tension sets)")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)

    ax = axes[2]
    k = np.arange(len(NAMES))

    def unit(d):
        d = np.asarray(d)
        lo = np.where(LOG, np.log(LOWER), LOWER)
        hi = np.where(LOG, np.log(UPPER), UPPER)
        return (np.where(LOG, np.log(d), d) - lo) / (hi - lo)

    ax.plot(k, unit(INITIAL), "o", mfc="none", label="initial")
    ax.plot(k, unit(REFERENCE), "r*", ms=10, label="reference (hidden)")
    ax.plot(k, unit(runs["Levenberg-Marquardt"]["design"]), "k.", label="LM")
    ax.plot(k, unit(runs["Nelder-Mead"]["design"]), "x", label="Nelder-Mead")
    ax.set_xticks(k, NAMES, rotation=60, ha="right", fontsize=8)
    ax.set_ylim(-0.05, 1.05)
    ax.set_ylabel("position between the bounds")
    ax.set_title("design variables (E and r trade off: not all identifiable)")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    main()
