"""System identification: E, damping and a tip mass from a noisy tip trajectory.

A soft rod (0.5 m, radius 1 cm, rho 1000 kg/m^3, clamped horizontally along x,
gravity -z) carries a small rigid body at its tip (a 2 x 2 cm cylinder on a fixed
joint). It bends in the x-z plane only: bending about y with quadratic Legendre
strain, 3 DoF. Released straight and at rest, it sags and swings about its hanging
shape, damped by the Kelvin-Voigt material damping. Three parameters are recovered
from the measured tip position (x, z): Young's modulus E, the damping eta and the tip
mass m (true values 10 MPa, 1e5 Pa s, 50 g).

Data: the tip at ``--samples`` evenly spaced times over ``--t1`` seconds, simulated
with the true parameters at a quarter of the fit's step, plus Gaussian noise whose
standard deviation is ``--noise`` (default 1 %) of each coordinate's range over the
trajectory. Fit: Levenberg-Marquardt on the log parameters (positive by
construction, and relative errors become absolute ones), starting 40 % low in E,
50 % high in eta and 30 % low in m. The residuals are divided by the noise level,
so at the optimum their RMS is ~1 and ``(J^T J)^-1`` estimates the covariance of
the log parameters (its square-rooted diagonal: the relative standard deviation).

The Jacobian is forward-mode autodiff through ``sj.simulate`` (``diffrax.ForwardMode``
adjoint), the three parameters' ``jax.jvp`` under ``jax.vmap`` (forward mode is
cheap: one primal integration, the tangents batched). Under ``lax.map`` instead
(each jvp with its own primal) the program compiled in the same time (4.5-5.6 s
against 5.0-5.7 s on a 2-core CPU, 2026-11-25) and ran 10-25 % slower (0.55-0.64
against 0.45-0.59 s per evaluation); earlier versions of sorojax and JAX had
compiled the vmapped jvps in 44 s. The model's structure
never changes: the parameters enter by ``eqx.tree_at`` on array leaves inside one
compiled program, which serves the data and every LM step.
Steps are constant (``adaptive=False``, ``--dt``, ROS34PW2: L-stable, so the damped
fast modes do not limit the step): adaptive step control makes the trajectory a
piecewise smooth function of the parameters (the accepted step sequence jumps), which
spoils both the Gauss-Newton model and any finite-difference check (measured at
rtol 1e-6: forward mode and central differences differ by ~1e-6 of the Jacobian
whatever the difference step, against 7e-9 at step 1e-4 with constant steps, and
it took 1614 steps for 1.5 s against 75). At the default step (20 ms) the
integration error (against a quarter step) is ~1.3e-4 m, 3 % of the noise; at 10 ms
it is 2e-5 m, and the fitted values move by at most 0.1 %, a tenth of their
standard deviations, while each evaluation takes twice as long (263 against 148 ms,
2-core CPU, 2026-11-26; the whole first run 12.2 against 10.2 s). E and m are 98 %
correlated (the hanging sag fixes mainly their ratio); the swing's frequency and
decay separate them.

Prints the recovered values, their errors and standard deviations, the iterations,
the residual RMS against the noise and the wall times (data and fit, including the
compile or a load from the persistent cache; the median of the fit's evaluations of
the residuals and their Jacobian, all with the program compiled by the data's call);
writes the measured and fitted tip trajectories and the parameter errors per
iteration to a PNG.

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


def levenberg_marquardt(residuals, x0, max_iterations=40, xtol=1e-4, max_step=0.5):
    """Minimise ``|r(x)|^2 / 2`` by Levenberg-Marquardt (Marquardt's scaling).

    Args:
        residuals: ``x -> (r (N,), J (N, n))``.
        x0: starting point ``(n,)``.
        max_iterations: most evaluations of ``residuals`` after the first.
        xtol: stop when an accepted step's largest component is below this (default
            1e-4: in log parameters, a relative change of 0.01 %, a hundredth of the
            fit's standard deviations here; 1e-6 took one more evaluation for the
            same values to 4 digits of their errors).
        max_step: largest change of any component in one step.

    Returns:
        ``(x, r, J, path, evaluations, converged)``; ``path`` holds the accepted
        iterates; ``converged`` is False when ``max_iterations`` ran out first.
    """
    x = np.asarray(x0, dtype=float)
    r, J = residuals(x)
    cost, lam, path, evaluations = 0.5 * r @ r, 1e-3, [x], 1
    while evaluations <= max_iterations:
        A, g = J.T @ J, J.T @ r
        step = np.linalg.solve(A + lam * np.diag(np.diag(A)), -g)
        # Trust the linear model within a factor e^max_step per parameter: from a
        # poor start the Gauss-Newton step can run a mass to ~0 (measured: 1e-6 m).
        step *= min(1.0, max_step / np.abs(step).max())
        r_new, J_new = residuals(x + step)
        evaluations += 1
        cost_new = 0.5 * r_new @ r_new
        if np.isfinite(cost_new) and cost_new < cost:
            x, r, J, cost = x + step, r_new, J_new, cost_new
            path.append(x)
            lam = max(lam / 3.0, 1e-9)
            if np.abs(step).max() < xtol:
                return x, r, J, np.array(path), evaluations, True
        else:  # rejected (or the integration failed): shorter, more gradient-like
            lam *= 4.0
    return x, r, J, np.array(path), evaluations, False


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
    sj.enable_compilation_cache()  # later runs load the compiled program
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    path = out / "system_identification.png"
    if path.exists() and not args.overwrite:
        raise SystemExit(f"{path} exists; pass --overwrite to replace it")

    ts = np.linspace(0.0, args.t1, args.samples)
    x_true = np.log(TRUE)
    x0 = x_true + np.log(START)

    # Data: the true trajectory at a quarter step (the same compiled program) + noise.
    t_start = time.perf_counter()
    clean = np.asarray(tip_and_jacobian(x_true, ts, args.dt / 4)[0])
    sigma = args.noise * np.ptp(clean, axis=0)  # per coordinate [m]
    rng = np.random.default_rng(args.seed)
    measured = clean + sigma * rng.standard_normal(clean.shape)

    evaluated = {}  # (log p, dt) -> (tips, J): the figure reuses the fit's
    seconds = []  # wall time of each fit evaluation (compiled by the data's call)

    def evaluate(x, dt):
        key = (np.asarray(x, dtype=float).tobytes(), float(dt))
        if key not in evaluated:
            t = time.perf_counter()
            evaluated[key] = tuple(np.asarray(a) for a in tip_and_jacobian(x, ts, dt))
            seconds.append(time.perf_counter() - t)
        return evaluated[key]

    def residuals(x):
        tips, J = evaluate(x, args.dt)
        r = ((tips - measured) / sigma).ravel()
        return r, (J / sigma[:, None]).reshape(r.size, -1)

    x, r, J, xs, evaluations, converged = levenberg_marquardt(residuals, x0)
    seconds_fit = time.perf_counter() - t_start
    # warm cost of one (r, J): the median of the fit's evaluations (the data's call,
    # at a quarter step, compiled the program)
    seconds_eval = float(np.median(seconds[1:]))
    if not np.all(np.isfinite(r)):
        raise RuntimeError("the fit's last integration failed")
    std = np.sqrt(np.diag(np.linalg.inv(J.T @ J)))  # of log p: relative
    rel_err = np.exp(x - x_true) - 1.0
    step_error = np.abs(evaluate(x_true, args.dt)[0] - clean)
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
        f"{len(xs) - 1} accepted LM steps, {evaluations} evaluations of (r, J); "
        f"residual RMS {rms:.3f} x noise; {seconds_fit:.1f} s (data and fit, incl. "
        f"compile or cache load); one (r, J) compiled: {1e3 * seconds_eval:.0f} ms "
        "(median of the fit's)"
    )

    fitted = evaluate(x, args.dt)[0]
    initial = evaluate(x0, args.dt)[0]
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
    errors = np.abs(np.exp(xs - x_true) - 1.0)
    for i, name in enumerate(NAMES):
        (line,) = a2.semilogy(errors[:, i], "o-", ms=4, label=name)
        a2.axhline(std[i], color=line.get_color(), ls=":", lw=1)
    a2.set_xlabel("accepted Levenberg-Marquardt step")
    a2.set_ylabel("|relative error|  (dotted: 1-sigma estimate)")
    a2.legend()
    a2.grid(alpha=0.3, which="both")
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
        "iterations": len(xs) - 1,
        "evaluations": evaluations,
        "converged": converged,
        "residual_rms": rms,
        "sigma": sigma,
        "ts": ts,
        "dt": args.dt,
        "seconds_fit": seconds_fit,
        "seconds_evaluation": seconds_eval,
    }


if __name__ == "__main__":
    main()
