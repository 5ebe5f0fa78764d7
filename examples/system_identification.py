"""System identification: E, damping and a tip mass from a noisy tip trajectory.

What this example teaches: how to fit a model's physical parameters to measured
motion with optimistix's Levenberg-Marquardt, its Jacobian taken by forward-mode
autodiff through ``sorojax.simulate``, and how to read the fit's uncertainty from
that Jacobian. The solver is stepped from Python (``init``, ``step`` and
``terminate``, as ``optx.least_squares`` runs them) and each step is given the
residuals and Jacobian at its trial point by the program that makes the data: the
integration, with its tangents, is compiled once.

The robot: a soft rod (0.5 m, radius 1 cm, rho 1000 kg/m^3, clamped horizontally
along x, gravity -z) carrying a small rigid body at its tip (a 2 x 2 cm cylinder on
a fixed joint). It bends in the x-z plane only: bending about y with quadratic
Legendre strain, 3 DoF. Released straight and at rest, it sags and swings about its
hanging shape, damped by the Kelvin-Voigt material damping. Three parameters are
recovered from the measured tip position (x, z): Young's modulus E, the damping eta
and the tip mass m (true values 10 MPa, 1e5 Pa s, 50 g).

Data: the tip at ``--samples`` evenly spaced times over ``--t1`` seconds, simulated
with the true parameters at a quarter of the fit's step, plus Gaussian noise whose
standard deviation is ``--noise`` (default 1 %) of each coordinate's range over the
trajectory.

Fit: the unknowns are the log parameters (positive by construction, and relative
errors become absolute ones), starting 40 % low in E, 50 % high in eta and 30 % low
in m. The residuals are divided by the noise level, so at the optimum their RMS is
~1 and ``(J^T J)^-1`` estimates the covariance of the log parameters (its
square-rooted diagonal: the relative standard deviations). E and m come out
strongly correlated (the hanging sag fixes mainly their ratio); the swing's
frequency and decay separate them.

Three choices make the fit work:

- The parameters enter the model by ``eqx.tree_at`` on array leaves, so the model's
  structure never changes and one compiled program serves every evaluation.
- ``adjoint=diffrax.ForwardMode()``: derivatives by forward mode, cheap for three
  parameters (one primal integration, the tangents batched).
- Constant steps (``adaptive=False``, ``--dt``, ROS34PW2: L-stable, so the damped
  fast modes do not limit the step). With adaptive steps the accepted step sequence
  jumps as the parameters change, so the trajectory is only piecewise smooth in
  them, which spoils the Gauss-Newton model and any finite-difference check. At the
  default 20 ms step the integration error (against a quarter step) is ~1.3e-4 m,
  3 % of the noise.

Prints the recovered values, their errors and standard deviations, the solver's
steps, the residual RMS against the noise and the wall time of the data and the fit
(each including its compile, or a load from the persistent cache); writes the
measured, fitted and initial tip trajectories and the recovered parameters with
their error bars to a PNG.

Run::

    python examples/system_identification.py [--t1 3] [--samples 61] [--out DIR]
"""

import argparse
import functools
import math
import pathlib
import time

import jax

jax.config.update("jax_enable_x64", True)

import diffrax  # noqa: E402
import equinox as eqx  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import matplotlib  # noqa: E402
import numpy as np  # noqa: E402
import optimistix as optx  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import sorojax as sj  # noqa: E402

sj.set_runtime_flags()  # XLA's CPU runtime flags: before any JAX array exists

NAMES = ("E", "eta", "m_tip")
UNITS = ("Pa", "Pa s", "kg")
TRUE = (1e7, 1e5, 0.05)  # E [Pa], eta [Pa s], tip mass [kg]
START = (0.6, 1.5, 0.7)  # initial guess / true value
LENGTH, RADIUS, RHO = 0.5, 0.01, 1000.0


def rod_with_tip_mass(E=TRUE[0], eta=TRUE[1], m_tip=TRUE[2]) -> sj.Linkage:
    """The clamped planar rod (3 DoF) with a rigid tip body of mass ``m_tip`` [kg]."""
    rod = sj.SoftLink(
        [
            sj.Division(
                LENGTH,
                sj.CircularSection(RADIUS),
                sj.LegendreBasis((0, 1, 0, 0, 0, 0), 2),
            )
        ],
        sj.Material(E=E, poisson=0.5, rho=RHO, eta=eta),
    )
    # Inertia: the 2 x 2 cm cylinder's, scaled to the given mass.
    tip = sj.RigidLink(
        sj.Joint("N"), length=0.02, section=sj.CircularSection(0.01), mass=m_tip
    )
    return sj.Linkage([rod, tip], parents=(0, 1), gravity=(0.0, 0.0, -9.81))


BASE = rod_with_tip_mass()


def with_parameters(log_p) -> sj.Linkage:
    """:data:`BASE` with E, eta and the tip mass set to ``exp(log_p)`` (leaves only)."""
    p = jnp.exp(log_p)
    return eqx.tree_at(
        lambda lk: (lk.links[0].material.E, lk.links[0].material.eta, lk.links[1].mass),
        BASE,
        (p[0], p[1], p[2]),
    )


def tip_xz(log_p, ts, dt):
    """Tip (x, z) [m] at the times ``ts`` ``(n,)``, released straight at t = 0."""
    linkage = with_parameters(log_p)
    traj = sj.simulate(
        linkage,
        ts[-1],
        ts=ts,
        solver="ros34pw2",
        adaptive=False,
        dt0=dt,
        max_steps=8192,
        adjoint=diffrax.ForwardMode(),  # forward-mode derivatives through the solve
        throw=False,
    )
    xz = jax.vmap(lambda q: sj.tip_pose(linkage, q)[jnp.array([0, 2]), 3])(traj.q)
    ok = traj.result == sj.RESULTS.successful
    return jnp.where(ok, xz, jnp.nan)


def _tip_and_jacobian(log_p, ts, dt):
    def column(v):
        return jax.jvp(lambda x: tip_xz(x, ts, dt), (log_p,), (v,))

    # The jvps under vmap: the primal integration once, the 3 tangents batched.
    eye = jnp.eye(log_p.shape[0], dtype=log_p.dtype)
    tip, cols = jax.vmap(column, out_axes=(None, 0))(eye)
    return tip, jnp.moveaxis(cols, 0, -1)


@functools.cache
def _compiled():
    return jax.jit(_tip_and_jacobian, compiler_options=sj.compiler_options())


def tip_and_jacobian(log_p, ts, dt):
    """Tip (x, z) ``(n, 2)`` [m] and its derivative ``(n, 2, 3)`` w.r.t. ``log_p``.

    One compiled program for every ``log_p`` and ``dt`` (``ts`` of a given length).
    A failed integration gives NaNs.
    """
    log_p = jnp.asarray(log_p, dtype=float)
    return _compiled()(log_p, jnp.asarray(ts, dtype=float), jnp.asarray(dt, float))


LM = optx.LevenbergMarquardt(rtol=1e-6, atol=1e-6)
"""The solver: it stops when both the step in the log parameters and the change of
the residuals are below 1e-6 (relative, or absolute: 1e-6 of the noise), far below
the fit's standard deviations."""


def _evaluated(r, jac, x_eval):
    """The residuals as one step of the solver sees them.

    A Levenberg-Marquardt step of optimistix evaluates its function once, with the
    Jacobian, at the trial point ``state.y_eval``. Given the residuals ``r`` and
    their Jacobian ``jac`` there (from :func:`tip_and_jacobian`, the program that
    also makes the data and the uncertainty), the affine map ``r + jac (x -
    x_eval)`` has that value and that Jacobian at ``x_eval``: the step's program
    then holds no integration, and the integration is compiled once.
    """

    def fn(x, args):
        return r + jac @ (x - x_eval), None

    return fn


def _lm_init(x, r, jac):
    fn = _evaluated(r, jac, x)
    f_struct, aux_struct = jax.eval_shape(fn, x, None)
    state = LM.init(fn, x, None, {}, f_struct, aux_struct, frozenset())
    return state, *LM.terminate(fn, x, None, {}, state, frozenset())


def _lm_step(x, state, r, jac):
    fn = _evaluated(r, jac, state.y_eval)
    new_x, state, _ = LM.step(fn, x, None, {}, state, frozenset())
    done, result = LM.terminate(fn, x, None, {}, state, frozenset())
    finite = jnp.all(jnp.isfinite(x))
    result = optx.RESULTS.where(finite, result, optx.RESULTS.nonfinite)
    return new_x, state, done, result


@functools.cache
def _fit_programs():
    # equinox's jit: the solver's state holds static parts (the step's jaxpr)
    return sj.jit(_lm_init), sj.jit(_lm_step)


def residuals_and_jacobian(log_p, ts, measured, sigma, dt):
    """Tip misfit in noise units ``(2 n,)`` and its Jacobian ``(2 n, 3)``.

    ``(tip(log_p) - measured) / sigma`` (``measured`` ``(n, 2)`` [m], ``sigma``
    ``(2,)`` [m]) and its derivative w.r.t. ``log_p``, from
    :func:`tip_and_jacobian`.
    """
    tip, J = (np.asarray(a) for a in tip_and_jacobian(log_p, ts, dt))
    r = ((tip - measured) / sigma[None, :]).ravel()
    return r, (J / sigma[None, :, None]).reshape(r.size, -1)


def fit(x0, ts, measured, sigma, dt, max_steps=40):
    """Levenberg-Marquardt from ``x0``: ``(log parameters, result code, steps)``.

    optimistix's solver stepped from Python (``init``, ``step``, ``terminate``, as
    ``optx.least_squares`` runs them), each step given the residuals and Jacobian
    at its trial point by :func:`tip_and_jacobian`: ``max_steps`` evaluations at
    most. It stops when both the step in the log parameters and the change of the
    residuals are below 1e-6 (relative, or absolute: 1e-6 of the noise), far below
    the fit's standard deviations.
    """
    lm_init, lm_step = _fit_programs()
    measured, sigma = np.asarray(measured, float), np.asarray(sigma, float)
    x = jnp.asarray(x0, dtype=float)
    n_r = measured.size
    state, done, result = lm_init(x, jnp.zeros(n_r), jnp.zeros((n_r, x.shape[0])))
    steps = 0
    while not bool(done) and result == optx.RESULTS.successful and steps < max_steps:
        r, jac = residuals_and_jacobian(state.y_eval, ts, measured, sigma, dt)
        x, state, done, result = lm_step(x, state, jnp.asarray(r), jnp.asarray(jac))
        steps += 1
    if result == optx.RESULTS.successful and not bool(done):
        result = optx.RESULTS.nonlinear_max_steps_reached
    return x, result, steps


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--t1", type=float, default=3.0, help="measured span [s]")
    ap.add_argument("--samples", type=int, default=61, help="measured times")
    ap.add_argument("--dt", type=float, default=0.02, help="fit's constant step [s]")
    ap.add_argument("--noise", type=float, default=0.01, help="noise / range")
    ap.add_argument("--seed", type=int, default=0, help="noise seed")
    ap.add_argument("--out", default=".", help="folder for the PNG")
    ap.add_argument("--overwrite", action="store_true", help="replace an old PNG")
    args = ap.parse_args(argv)
    sj.enable_compilation_cache()  # later runs load the compiled programs
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    path = out / "system_identification.png"
    if path.exists() and not args.overwrite:
        raise SystemExit(f"{path} exists; pass --overwrite to replace it")

    ts = np.linspace(0.0, args.t1, args.samples)
    x_true = np.log(TRUE)
    x0 = x_true + np.log(START)

    # Data: the true trajectory at a quarter step (the same compiled program) + noise.
    t = time.perf_counter()
    clean = np.asarray(tip_and_jacobian(x_true, ts, args.dt / 4)[0])
    sigma = args.noise * np.ptp(clean, axis=0)  # per coordinate [m]
    rng = np.random.default_rng(args.seed)
    measured = clean + sigma * rng.standard_normal(clean.shape)
    seconds_data = time.perf_counter() - t

    # The fit: optimistix's Levenberg-Marquardt, stepped from Python.
    t = time.perf_counter()
    x, result, steps = fit(x0, ts, measured, sigma, args.dt)
    x, steps = np.asarray(x), int(steps)
    seconds_fit = time.perf_counter() - t
    converged = bool(result == optx.RESULTS.successful)

    # Uncertainty: the Jacobian at the optimum, in noise units.
    tips, J = (np.asarray(a) for a in tip_and_jacobian(x, ts, args.dt))
    if not np.all(np.isfinite(tips)):
        raise RuntimeError("the integration at the fitted parameters failed")
    r = ((tips - measured) / sigma).ravel()
    J = (J / sigma[:, None]).reshape(r.size, -1)
    std = np.sqrt(np.diag(np.linalg.inv(J.T @ J)))  # of log p: relative
    rel_err = np.exp(x - x_true) - 1.0
    step_error = np.abs(np.asarray(tip_and_jacobian(x_true, ts, args.dt)[0]) - clean)
    rms = float(np.sqrt(np.mean(r**2)))

    print(
        f"{BASE.n_dof} DoF, {args.samples} samples over {args.t1} s, noise "
        f"{args.noise:.0%} of the range = {sigma[0] * 1e3:.2f} / {sigma[1] * 1e3:.2f} "
        f"mm (x / z); constant step {args.dt} s (error vs a quarter step "
        f"{step_error.max():.1e} m)"
    )
    for i, name in enumerate(NAMES):
        print(
            f"{name:6s} true {TRUE[i]:.4g}  start {math.exp(x0[i]):.4g}  fitted "
            f"{math.exp(x[i]):.5g} {UNITS[i]}: error {rel_err[i]:+.2%} "
            f"(1-sigma {std[i]:.2%})"
        )
    print(
        f"Levenberg-Marquardt: {steps} steps, "
        f"{'converged' if converged else 'NOT converged'}; residual RMS {rms:.3f} x "
        f"noise; wall time (incl. compile or cache load) data {seconds_data:.1f} s, "
        f"fit {seconds_fit:.1f} s"
    )

    fitted = tips
    initial = np.asarray(tip_and_jacobian(x0, ts, args.dt)[0])
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4.2))
    for k, (label, color) in enumerate((("x", "tab:blue"), ("z", "tab:orange"))):
        a1.plot(ts, measured[:, k], ".", color=color, ms=4, label=f"measured {label}")
        a1.plot(ts, fitted[:, k], "-", color=color, label=f"fitted {label}")
        a1.plot(ts, initial[:, k], ":", color=color, alpha=0.6, label=f"start {label}")
    a1.set_xlabel("t [s]")
    a1.set_ylabel("tip position [m]")
    lo, hi = min(measured.min(), initial.min()), max(measured.max(), initial.max())
    a1.set_ylim(lo - 0.05 * (hi - lo), hi + 0.35 * (hi - lo))  # room for the legend
    a1.legend(fontsize=8, ncol=3, loc="upper center")
    a1.grid(alpha=0.3)
    k = np.arange(len(NAMES))
    a2.errorbar(k, 100 * rel_err, yerr=100 * std, fmt="o", capsize=4, label="fitted")
    a2.plot(k, 100 * (np.asarray(START) - 1.0), "x", ms=8, label="start")
    a2.axhline(0.0, color="k", lw=1)
    a2.set_xticks(k, NAMES)
    a2.set_ylabel("error vs true value [%]  (bars: 1-sigma)")
    a2.legend()
    a2.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    print(f"wrote {path}")
    return {
        "true": dict(zip(NAMES, TRUE, strict=True)),
        "initial": dict(zip(NAMES, np.exp(x0).tolist(), strict=True)),
        "recovered": dict(zip(NAMES, np.exp(x).tolist(), strict=True)),
        "rel_error": dict(zip(NAMES, rel_err.tolist(), strict=True)),
        "rel_std": dict(zip(NAMES, std.tolist(), strict=True)),
        "log_p": x,
        "steps": steps,
        "converged": converged,
        "residual_rms": rms,
        "sigma": sigma,
        "ts": ts,
        "dt": args.dt,
        "seconds_data": seconds_data,
        "seconds_fit": seconds_fit,
    }


if __name__ == "__main__":
    main()
