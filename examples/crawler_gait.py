"""A soft crawler's gait, tuned by gradient through the contact dynamics.

A soft rod (0.3 m, r 1 cm, E 1 MPa, 3 bending coordinates about y) lies on a floor
with anisotropic friction, as a snake's scales or an inchworm's bristles have it:
sliding forward along the rod (its +x) meets mu_f = 0.1, sliding backward or sideways
mu_b = 0.6. Internal bending moments drive it (muscles, or a pair of tendons): the
rear half and the front half each bend with ``A sin(2 pi f t)`` and
``A sin(2 pi f t - phi)`` [N m per m of rod]. Arching lifts the middle and pulls the
ends together; the friction lets the ends move forward only, so every cycle ratchets
the rod forward, by an amount that depends on the amplitude A and the phase lag phi.

The script:

1. simulates one gait (constant 0.5 ms steps of linearly implicit Euler with the
   contacts' stiffness and friction in W, so that the distance is a smooth function
   of A and phi; at the ascent's start it differs from ROS34PW2 at 1 ms steps by
   2.5 % and takes a fifth of the time);
2. maps distance per cycle over a grid of (A, phi), all rollouts in one ``vmap``;
3. climbs the same map by gradient ascent with forward-mode derivatives through
   ``simulate`` (``jax.jacfwd``, ``diffrax.ForwardMode()``), the step bounded by a
   trust region in (A / A_max, phi / pi): from a start away from the grid's best
   (it finds a local maximum), and from the grid's best cell (it refines it);
4. checks the gradient at the start against central differences;
5. plots the gait's snapshots, the map with the grid's best and the ascent's path.

Run::

    .venv/bin/python examples/crawler_gait.py [--out DIR] [--cycles 2] [--grid 5]
"""

import argparse
import pathlib
import sys
import time

import jax

jax.config.update("jax_enable_x64", True)

import diffrax  # noqa: E402
import equinox as eqx  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

import sorojax as sj  # noqa: E402

# XLA's CPU runtime flags, before any JAX array exists; one runtime thread: the
# gradient's program (small operations, run one call at a time) runs 1.3x faster
sj.set_runtime_flags(threads=1)

G = 9.81
L, R, RHO, E = 0.3, 0.01, 1000.0, 1e6
FREQ = 2.0  # gait frequency [Hz]
A_MAX = 0.05  # largest amplitude of the grid [N m / m]
DT = 5e-4  # constant step [s]


def bending(t, q, qd, kin, u, amplitude, phase, front):
    """Internal bending moment per length about the body y axis at every point."""
    w = 2 * jnp.pi * FREQ
    m = amplitude * jnp.where(front > 0.5, jnp.sin(w * t - phase), jnp.sin(w * t))
    m = jnp.where(front >= 0, m, 0.0)  # only rod points (front: -1 elsewhere)
    zeros = jnp.zeros_like(m)
    return jnp.stack([zeros, m, zeros, zeros, zeros, zeros], axis=1)


def crawler(amplitude, phase) -> sj.Linkage:
    """The rod on its floor, driven with ``amplitude`` [N m/m] and ``phase`` [rad]."""
    rod = sj.SoftLink(
        [
            sj.Division(
                L, sj.CircularSection(R), sj.LegendreBasis((0, 1, 0, 0, 0, 0), 2)
            )
        ],
        sj.Material(E=E, poisson=0.5, rho=RHO, eta=2e3),
        joint=sj.Joint("A", axis=(0, 1, 0)),  # planar: x, z and pitch
    )
    place = np.eye(4)
    place[2, 3] = R
    law = sj.ContactLaw(
        stiffness=2e4, smoothing=1e-5, damping=20.0,
        static_friction=0.6, forward_friction=0.1, stick_velocity=1e-2,
    )  # fmt: skip
    contact = sj.Contact(sj.Plane(), law, spacing=0.03)
    shape = sj.Linkage([rod], placements=place[None], contact=contact)
    lay = shape.layout
    # -1 off the rod, 0 on its rear half, 1 on its front half (static, from the layout)
    front = np.where(lay.point_kind == 2, (lay.point_X1 >= 0.5).astype(float), -1.0)
    hook = eqx.Partial(bending, amplitude=amplitude, phase=phase,
                       front=jnp.asarray(front))  # fmt: skip
    return sj.Linkage(
        [rod], placements=place[None], gravity=(0, 0, -G), contact=contact,
        custom_actuation=hook,
    )  # fmt: skip


def centre_x(lk, q):
    """Mean x of the rod's points [m]."""
    g = sj.forward_kinematics(lk, q)
    rod = np.where(lk.layout.point_kind == 2)[0]
    return jnp.mean(g[rod, 0, 3])


def distance_per_cycle(params, cycles, n_save=2):
    """Forward travel of the rod's centre per cycle [m] for ``(A, phi)``."""
    lk = crawler(params[0], params[1])
    T = cycles / FREQ
    tr = sj.simulate(
        lk, T, solver="rosenbrock_euler", dt0=DT, n_save=n_save,
        adjoint=diffrax.ForwardMode(), throw=False,
    )  # fmt: skip
    return (centre_x(lk, tr.q[-1]) - centre_x(lk, tr.q[0])) / cycles, tr


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--out", default=".")
    p.add_argument("--cycles", type=int, default=2)
    p.add_argument("--grid", type=int, default=5)
    p.add_argument("--ascent-steps", type=int, default=8)
    p.add_argument("--overwrite", action="store_true")
    a = p.parse_args(argv)
    out = pathlib.Path(a.out) / "crawler_gait.png"
    if out.exists() and not a.overwrite:
        sys.exit(f"{out} exists: give --overwrite to replace it.")
    sj.enable_compilation_cache()
    t_start = time.perf_counter()

    def dpc(params):
        return distance_per_cycle(params, a.cycles)[0]

    def distance_and_gradient(params):
        """The distance and its gradient (forward mode: two tangents) at once."""
        grad, value = jax.jacfwd(lambda x: (dpc(x),) * 2, has_aux=True)(params)
        return value, grad

    # 2. the map over a grid, every rollout in one program; then gradient ascent.
    # Each program is traced here and compiled in a worker thread (XLA's compile does
    # not hold Python's lock) while this thread traces the next or runs the last:
    # the grid's; the gradient's; one rollout's (for the central differences and the
    # gait drawn at the end); long_run: sorojax's XLA options for programs that run
    # many times.
    As = np.linspace(A_MAX / a.grid, A_MAX, a.grid)
    phis = np.linspace(0.0, 2 * np.pi, a.grid, endpoint=False)
    grid = jnp.asarray([(A, ph) for A in As for ph in phis])
    x0 = jnp.asarray([0.3 * A_MAX, 0.5])  # the ascent's start
    on_grid = sj.jit(jax.vmap(dpc), tiered=False, long_run=True)
    value_and_grad = sj.jit(distance_and_gradient, tiered=False, long_run=True)
    rollout = sj.jit(lambda x: distance_per_cycle(x, a.cycles, n_save=9),
                     tiered=False, long_run=True)  # fmt: skip
    t0 = time.perf_counter()
    on_grid.prepare(grid)
    value_and_grad.prepare(x0)
    rollout.prepare(x0)
    values = np.asarray(on_grid(grid)).reshape(a.grid, a.grid)
    t_grid = time.perf_counter() - t0
    i, j = np.unravel_index(np.nanargmax(values), values.shape)
    best_grid = (As[i], phis[j], values[i, j])
    print(
        f"grid {a.grid}x{a.grid}: best {best_grid[2] * 1e3:.2f} mm/cycle at "
        f"A = {best_grid[0]:.3f} N, phi = {best_grid[1]:.2f} rad ({t_grid:.1f} s, "
        "the other programs' traces included)"
    )

    # 3. gradient ascent (forward mode: two parameters): steps of a trust radius
    # in the scaled variables (A / A_max, phi / pi), along the scaled gradient
    scale = np.array([A_MAX, np.pi])
    lower, upper = np.array([0.02 * A_MAX, -np.inf]), np.array([A_MAX, np.inf])
    t0 = time.perf_counter()
    v0, g0 = value_and_grad(x0)

    def ascend(x, v, g):
        """Trust-region steepest ascent; returns the end and its path."""
        path, radius = [np.asarray(x)], 0.25
        for _ in range(a.ascent_steps):
            gs = np.asarray(g) * scale
            step = radius * scale * gs / max(np.linalg.norm(gs), 1e-30)
            trial = jnp.asarray(np.clip(x + step, lower, upper))
            vt, gt = value_and_grad(trial)
            if vt > v:
                x, v, g, radius = trial, vt, gt, min(2 * radius, 0.5)
                path.append(np.asarray(x))
            else:
                radius *= 0.5
        return x, v, np.array(path)

    x, v, path = ascend(x0, v0, g0)
    # and from the grid's best cell: the gradient refines what the grid found
    xb = jnp.asarray([best_grid[0], best_grid[1]])
    xr, vr, path_r = ascend(xb, *value_and_grad(xb))
    t_ascent = time.perf_counter() - t0
    print(
        f"ascent: {float(v0) * 1e3:.2f} -> {float(v) * 1e3:.2f} mm/cycle at "
        f"A = {float(x[0]):.3f} N, phi = {float(x[1]) % (2 * np.pi):.2f} rad; "
        f"from the grid's best: {best_grid[2] * 1e3:.2f} -> {float(vr) * 1e3:.2f} "
        f"mm/cycle at phi = {float(xr[1]) % (2 * np.pi):.2f} rad ({t_ascent:.1f} s)"
    )

    # 4. the start's gradient against central differences
    h = 1e-4 * scale
    fd = np.array(
        [
            (rollout(x0 + h * e)[0] - rollout(x0 - h * e)[0]) / (2 * h[k])
            for k, e in enumerate(np.eye(2))
        ]
    )
    rel = np.abs(np.asarray(g0) - fd) / np.maximum(np.abs(fd), 1e-12)
    print(f"gradient at the start {np.asarray(g0)} vs central differences {fd} "
          f"(relative {rel.max():.1e})")  # fmt: skip

    # 1. and 5. the gait at the ascent's result, and the figure
    best = xr if vr > v else x
    _, tr = rollout(best)
    lk = crawler(best[0], best[1])
    _figure(out, lk, tr, As, phis, values, [path, path_r], best_grid)
    print(f"wrote {out} ({time.perf_counter() - t_start:.1f} s in all)")
    return dict(grid=values, best_grid=best_grid, ascent=(np.asarray(x), float(v)),
                refined=(np.asarray(xr), float(vr)),
                start=(float(v0), np.asarray(g0), fd), path=path)  # fmt: skip


def _figure(out, lk, tr, As, phis, values, paths, best_grid):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 2, figsize=(11, 4))
    rod = np.where(lk.layout.point_kind == 2)[0]
    for k, q in enumerate(tr.q):
        g = np.asarray(sj.forward_kinematics(lk, q))
        ax[0].plot(g[rod, 0, 3], g[rod, 2, 3], color=plt.cm.viridis(k / len(tr.q)))
    ax[0].axhline(0.0, color="0.5", lw=3)
    ax[0].set(xlabel="x [m]", ylabel="z [m]", aspect="equal",
              title="gait snapshots (dark: start)")  # fmt: skip
    im = ax[1].pcolormesh(phis, As, values * 1e3, shading="nearest")
    fig.colorbar(im, ax=ax[1], label="mm per cycle")
    labels = ("gradient ascent", "refining the grid's best")
    for p_, label in zip(paths, labels, strict=True):
        ax[1].plot(p_[:, 1] % (2 * np.pi), p_[:, 0], ".-", label=label)
    ax[1].plot(best_grid[1], best_grid[0], "r*", ms=12, label="grid's best")
    ax[1].set(xlabel="phase lag phi [rad]", ylabel="amplitude A [N m/m]")
    ax[1].legend(loc="lower right")
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    main()
