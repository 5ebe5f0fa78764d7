"""The grasp's cable tension, minimised for a secure hold by gradient through contact.

examples/grasp.py's gripper closes on its 20 g ball with tension T in each cable,
lifts it 5 cm and holds it until ``t1``. The ball's slip (how far it fell behind the
palm from the lift's start to ``t1``, ``grasp.slip``) falls as T rises: too little
tension and the ball slides out; more holds it, and more still lets the curling
fingers draw it up toward the palm (a negative slip), but costs more. The objective

    J(T) = T + W * SIGMA * softplus((slip(T) - S_MAX) / SIGMA)      [N]

prices tension against slip: a hold is secure when the ball slips less than S_MAX
by ``t1``; beyond it every millimetre costs W * 1 mm of tension (W = 10 N/mm: an
almost hard limit), smoothed over SIGMA (0.1 mm, finer than the slip's change for a
0.1 N change of T in the holding regime) so that J has a continuous derivative.
At the minimum ``1 + W sigmoid((slip - S_MAX) / SIGMA) slip'(T) = 0``: the
tension where the slip, still falling at ``|slip'|`` mm per N, sits a few SIGMA
below S_MAX.

The script:

1. descends J from a poor start (6 N) with forward-mode derivatives through
   ``simulate`` (``jax.jvp``, ``diffrax.ForwardMode()``: one scalar parameter, so one
   tangent): a safeguarded Newton-type method, each step minimising
   ``T + penalty(slip)`` on a model of the slip built from its values and
   derivatives (its Taylor expansion, then its cubic Hermite interpolant once the
   minimum is bracketed), within a trust region (see ``descend``);
2. maps slip and J over a grid of tensions, the grid's rollouts and the central
   differences' in one ``vmap``;
3. checks d slip / dT at the start and at the descent's end against central
   differences (step H);
4. plots J and the slip against T with the descent's iterates, and writes the
   figures to a JSON file.

Each rollout is 2,800 constant 0.5 ms steps of the linearly implicit Euler solver
(``grasp.slip``; the hold is shortened to 0.6 s, ``t1`` = 1.4 s): a smooth function of
the tension, and the grid's rollouts run in lockstep. The descent ends at 3.820 N in 4
rollouts (adaptive Tsit5 at rtol 1e-4, ``--dt 0``: 3.835 N in 5 rollouts; 1 ms steps:
3.806 N), d slip / dT within 2.4e-5 of central differences; 54 s in all on 2 cores,
26 s of it the first rollout's compile (with adaptive Tsit5: 45 min at a load of 6-11).

Run::

    .venv/bin/python examples/grasp_tension.py [--out DIR] [--t1 1.4] [--grid 8]
        [--dt 5e-4]
"""

import argparse
import json
import pathlib
import sys
import time

import jax

jax.config.update("jax_enable_x64", True)

import diffrax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

import sorojax as sj  # noqa: E402

sj.set_runtime_flags()  # XLA's CPU runtime flags: before any JAX array exists

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import grasp  # noqa: E402

S_MAX = 1e-3  # slip allowed by t1 for a secure hold [m]
SIGMA = 1e-4  # smoothing of the limit [m]
W = 1e4  # price of slip beyond S_MAX [N/m]: 10 N per mm
H = 0.02  # central differences' step [N]
T_LO, T_HI = 1.0, 8.0  # the tensions the descent may try [N]


def penalty(slip):
    """``J`` [N] less the tension: the penalty on a slip [m] beyond ``S_MAX``."""
    return W * SIGMA * jax.nn.softplus((slip - S_MAX) / SIGMA)


def _slip_model(a, b):
    """The slip [m] against T from its values and derivatives at ``a`` and ``b``.

    ``a``, ``b``: ``(T, J, J', slip, slip')``. The cubic Hermite interpolant through
    both; with ``b`` None the first-order Taylor expansion at ``a``.
    """
    if b is None:
        return lambda T: a[3] + a[4] * (T - a[0])
    h = b[0] - a[0]

    def model(T):
        u = (T - a[0]) / h
        h00, h10 = 2 * u**3 - 3 * u**2 + 1, u**3 - 2 * u**2 + u
        h01, h11 = -2 * u**3 + 3 * u**2, u**3 - u**2
        return h00 * a[3] + h10 * h * a[4] + h01 * b[3] + h11 * h * b[4]

    return model


def descend(value_and_grad, T0, radius=1.0, max_rollouts=10, tol=0.005):
    """Minimise J over T from the slip and its forward-mode derivative.

    A safeguarded Newton-type method on one scalar: each step minimises J's
    exact outer function, ``T + penalty(slip)``, on a model of the slip, within a
    trust region. The best tension so far, ``x``, lies in a bracket ``[lo, hi]`` of
    tensions tried (an end not found yet is open); the step goes to the side where
    J' says that J falls. While that side is open the model is the slip's
    first-order Taylor expansion at ``x`` and the step at most ``radius`` [N]
    (doubling after each step, up to 2 N); once the side is closed by ``p``, the
    model is the cubic Hermite interpolant of the slip through ``x`` and ``p``, and
    the step stays within 2-98 % of the way from ``x`` to ``p`` (the model's minimum
    found on a 2001-point grid of that interval). A tension with a lower J becomes
    ``x`` and the old ``x`` the bracket's end on its side; one with a higher J
    becomes the end on its side. Stops when the step is under ``tol`` [N] or after
    ``max_rollouts`` rollouts.

    Args:
        value_and_grad: ``T -> (J, J', slip, slip')``, one rollout.
        T0: the start [N].
        radius: the first step [N].
        max_rollouts: the most rollouts.
        tol: the smallest step [N].

    Returns:
        The rollouts in order: ``(T, J, J', slip, slip', best)``, ``best`` True at
        the one the descent ends on.
    """
    path = [(T0, *value_and_grad(T0))]
    x, lo, hi = path[0], None, None
    while len(path) < max_rollouts:
        p = lo if x[2] > 0 else hi
        if p is None:
            end = float(np.clip(x[0] - np.sign(x[2]) * radius, T_LO, T_HI))
            Ts = np.linspace(x[0], end, 2001)
            radius = min(2 * radius, 2.0)
        else:
            Ts = x[0] + np.linspace(0.02, 0.98, 2001) * (p[0] - x[0])
        model = _slip_model(x, p)
        c = float(Ts[np.argmin(Ts + np.asarray(penalty(jnp.asarray(model(Ts)))))])
        if abs(c - x[0]) < tol:
            break
        path.append((c, *value_and_grad(c)))
        t = path[-1]
        if t[1] < x[1]:  # the new best; the old one closes the bracket on its side
            lo, hi = (lo, x) if c < x[0] else (x, hi)
            x = t
        else:
            lo, hi = (t, hi) if c < x[0] else (lo, t)
    return [(*r, r is x) for r in path]


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--out", default=".")
    p.add_argument("--t1", type=float, default=1.4)
    p.add_argument("--grid", type=int, default=8)
    p.add_argument("--start", type=float, default=6.0)
    p.add_argument("--max-rollouts", type=int, default=10)
    p.add_argument(
        "--dt",
        type=float,
        default=5e-4,
        help="constant step [s] of the rollouts; 0: adaptive Tsit5",
    )
    p.add_argument("--overwrite", action="store_true")
    a = p.parse_args(argv)
    dt = a.dt or None
    out = pathlib.Path(a.out)
    png, js = out / "grasp_tension.png", out / "grasp_tension.json"
    for f in (png, js):
        if f.exists() and not a.overwrite:
            sys.exit(f"{f} exists: give --overwrite to replace it.")
    sj.enable_compilation_cache()
    lk = grasp.gripper()
    t_start = time.perf_counter()

    def slip_and_J(T):
        s = grasp.slip(lk, T, a.t1, adjoint=diffrax.ForwardMode(), dt=dt)
        return jnp.stack([T + penalty(s), s])

    @jax.jit
    def jvp(T):
        return jax.jvp(slip_and_J, (T,), (jnp.ones_like(T),))

    slips = jax.jit(jax.vmap(lambda T: grasp.slip(lk, T, a.t1, throw=False, dt=dt)))

    # 1. the descent: one forward-mode rollout per tension tried
    times = []

    def value_and_grad(T):
        t0 = time.perf_counter()
        (v, s), (g, ds) = (np.asarray(x) for x in jvp(jnp.asarray(T)))
        times.append(time.perf_counter() - t0)
        print(f"  T = {T:.3f} N: J = {v:.4f} N, dJ/dT = {g:+.4f}, slip = "
              f"{s * 1e3:.3f} mm, dslip/dT = {ds * 1e3:+.3f} mm/N "
              f"({times[-1]:.1f} s)", flush=True)  # fmt: skip
        return float(v), float(g), float(s), float(ds)

    print(f"descent from {a.start:g} N:")
    path = descend(value_and_grad, a.start, max_rollouts=a.max_rollouts)
    best = next(r for r in path if r[5])
    t_descent = sum(times)

    # 2. the grid and 3. the central differences, in one batch of rollouts
    Ts = np.linspace(1.5, 6.0, a.grid)
    checks = [path[0], best]
    batch = np.concatenate([Ts] + [[r[0] - H, r[0] + H] for r in checks])
    t0 = time.perf_counter()
    s_batch = np.asarray(slips(jnp.asarray(batch)))
    t_grid = time.perf_counter() - t0
    s_grid = s_batch[: a.grid]
    J_grid = Ts + np.asarray(penalty(jnp.asarray(s_grid)))
    k = int(np.nanargmin(J_grid))
    print(f"grid of {a.grid} tensions ({t_grid:.1f} s with the checks' "
          f"{2 * len(checks)} rollouts): best T = {Ts[k]:.2f} N, J = {J_grid[k]:.4f} "
          f"N, slip = {s_grid[k] * 1e3:.3f} mm")  # fmt: skip
    gradient_check = []
    for r, (sm, sp) in zip(checks, s_batch[a.grid :].reshape(-1, 2), strict=True):
        fd = (sp - sm) / (2 * H)
        rel = abs(r[4] - fd) / abs(fd)
        gradient_check.append(dict(T=r[0], dslip_dT=r[4], central_difference=fd,
                                   relative=rel))  # fmt: skip
        print(f"dslip/dT at {r[0]:.3f} N: forward mode {r[4] * 1e3:+.5f}, central "
              f"differences (h = {H} N) {fd * 1e3:+.5f} mm/N "
              f"(relative {rel:.1e})")  # fmt: skip
    print(f"descent: T = {best[0]:.3f} N, J = {best[1]:.4f} N, slip = "
          f"{best[3] * 1e3:.3f} mm, dJ/dT = {best[2]:+.2e}, {len(path)} rollouts, "
          f"{t_descent:.1f} s")  # fmt: skip

    results = dict(
        t1=a.t1, S_MAX=S_MAX, SIGMA=SIGMA, W=W, H=H,
        descent=dict(
            path=[dict(T=r[0], J=r[1], dJ_dT=r[2], slip=r[3], dslip_dT=r[4],
                       seconds=t)
                  for r, t in zip(path, times, strict=True)],
            T=best[0], J=best[1], slip=best[3], rollouts=len(path),
            seconds=t_descent,
        ),
        grid=dict(T=Ts.tolist(), slip=s_grid.tolist(), J=J_grid.tolist(),
                  best=dict(T=Ts[k], J=J_grid[k], slip=s_grid[k]),
                  rollouts=a.grid, seconds_with_checks=t_grid),
        gradient_check=gradient_check,
    )  # fmt: skip
    results = json.loads(json.dumps(results, default=float))
    js.write_text(json.dumps(results, indent=1))
    _figure(png, Ts, s_grid, J_grid, path)
    print(f"wrote {png} and {js} ({time.perf_counter() - t_start:.1f} s in all)")
    return results


def _figure(out, Ts, s_grid, J_grid, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    P = np.array([r[:5] for r in path])
    k = [r[5] for r in path].index(True)
    fig, ax = plt.subplots(1, 2, figsize=(11, 4))
    ax[0].semilogy(Ts, J_grid, "o-", color="0.5", label="grid")
    ax[0].semilogy(P[:, 0], P[:, 1], "C0.-", lw=0.8, label="descent (in order)")
    ax[0].semilogy(P[0, 0], P[0, 1], "C0s", label="start")
    ax[0].semilogy(P[k, 0], P[k, 1], "r*", ms=12, label="descent's end")
    ax[0].set(xlabel="cable tension T [N]", ylabel="J [N]",
              title=f"J = T + slip penalty (S_MAX = {S_MAX * 1e3:g} mm)")  # fmt: skip
    ax[0].legend()
    ax[1].plot(Ts, s_grid * 1e3, "o-", color="0.5", label="grid")
    ax[1].plot(P[:, 0], P[:, 3] * 1e3, "C0.", label="descent")
    ax[1].axhline(S_MAX * 1e3, color="k", ls="--", lw=0.8, label="S_MAX")
    # the forward-mode slopes at the descent's tensions
    for T, _, _, s, ds in P:
        dT = np.array([-0.2, 0.2])
        ax[1].plot(T + dT, (s + ds * dT) * 1e3, "C1", lw=1.5)
    ax[1].plot([], [], "C1", label="forward-mode d slip / dT")
    ax[1].set_yscale("symlog", linthresh=1.0)
    ax[1].set(xlabel="cable tension T [N]", ylabel="slip by t1 [mm]",
              title="the ball's slip in the fingers (< 0: drawn up)")  # fmt: skip
    ax[1].legend()
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    main()
