"""A two-finger soft gripper closes on a free ball, lifts it and holds it.

The palm is a rigid link on a prismatic joint whose height is prescribed; two soft
fingers (8 cm, r 6 mm, E 1 MPa, bending about one axis: 3 coordinates each) hang
from it on either side of a 2 cm ball (20 g, free joint) resting on the floor. A
cable inside each finger, 4 mm off its axis on the ball's side, curls it toward the
ball. The fingers' segments touch the ball's contact sphere (``Contact.rod_pairs``
with a rigid shape) with friction (mu 0.8); the ball and the fingertips touch the
floor.

Timeline: the tensions ramp to T over 0.3 s, the palm rises 5 cm between 0.4 and
0.8 s, then holds. The script simulates this for a few tensions (``grasp()``
defaults to the linearly implicit Euler solver ``"rosenbrock_euler"`` at a constant
2 ms step, the contacts' stiffness and friction in its W; see ``grasp()`` for its
accuracy against adaptive solvers), reports how far the ball slipped in the fingers
by the end, and plots the ball's and the palm's heights and each finger's total
contact force on the ball.

Run::

    .venv/bin/python examples/grasp.py [--out DIR] [--tensions 2 4] [--t1 1.8]
"""

import argparse
import pathlib
import sys
import time

import jax

jax.config.update("jax_enable_x64", True)

import equinox as eqx  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

import sorojax as sj  # noqa: E402
from sorojax.scenes import GRASP_LIFT, grasp_inputs  # noqa: E402

sj.set_runtime_flags()  # XLA's CPU runtime flags: before any JAX array exists

G = 9.81
FINGER, R_FINGER, R_BALL, M_BALL, GAP = 0.08, 0.006, 0.02, 0.02, 0.002
LIFT = GRASP_LIFT


def _turn_down(flip: bool) -> np.ndarray:
    """A finger frame: local x pointing down (-z); ``flip`` mirrors it about x."""
    R = np.array([[0.0, 0, 1], [0, 1, 0], [-1, 0, 0]])  # rot_y(pi/2): x -> -z
    return R @ np.diag([1.0, -1, -1]) if flip else R


def gripper(mu: float = 0.8) -> sj.Linkage:
    """Palm (link 1, prescribed height), fingers (links 2, 3), ball (link 4)."""
    palm = sj.RigidLink(
        sj.Joint("P", axis=(0, 0, 1)), length=0.08, mass=0.05,
        inertia=np.diag([1e-5] * 3), g_i=np.eye(4), g_f=np.eye(4),
    )  # fmt: skip
    finger = sj.SoftLink(
        [sj.Division(FINGER, sj.CircularSection(R_FINGER),
                     sj.LegendreBasis((0, 1, 0, 0, 0, 0), 2))],
        sj.Material(E=1e6, poisson=0.5, rho=1100.0, eta=500.0),
    )  # fmt: skip
    ball = sj.RigidLink(sj.Joint("F"), length=0.01, mass=M_BALL,
                        inertia=np.diag([0.4 * M_BALL * R_BALL**2] * 3),
                        g_i=np.eye(4), g_f=np.eye(4))  # fmt: skip
    x0 = R_BALL + R_FINGER + GAP
    place = np.stack([np.eye(4)] * 4)
    place[0, 2, 3] = FINGER + 0.01
    for k, side in ((1, -1.0), (2, 1.0)):
        place[k, :3, :3] = _turn_down(side > 0)
        place[k, :3, 3] = [side * x0, 0.0, 0.0]
    place[3, 2, 3] = R_BALL  # resting on the floor
    # the cable runs 4 mm off each finger's axis on the ball's side (local +z)
    cables = [sj.Cable([sj.CableSpan(k, sj.ConstantPath(0.0, 0.004))]) for k in (2, 3)]
    law = sj.ContactLaw(stiffness=2e3, smoothing=1e-5, damping=1.0,
                        static_friction=mu, stick_velocity=1e-2)  # fmt: skip
    contact = sj.Contact(sj.Plane(), law, shapes={4: sj.ContactSphere(R_BALL)},
                         rod_pairs=[(2, 4), (3, 4)], spacing=0.01)  # fmt: skip
    return sj.Linkage(
        [palm, finger, finger, ball], parents=(0, 1, 1, 0), placements=place,
        gravity=(0, 0, -G), actuators=[sj.JointActuator(1, prescribed=True), *cables],
        contact=contact,
    )  # fmt: skip


# u(t): palm height [m], then the two tensions [N] (in sorojax.scenes, so that the
# scene file examples/scenes/grasp.toml can name it)
inputs = grasp_inputs


def grasp(lk, tension, t1, n_save=61, solver="rosenbrock_euler", dt=2e-3,
          rtol=1e-4, atol=1e-7):  # fmt: skip
    """Simulate one grasp: ``(trajectory, ball height, palm height)``.

    By default constant 2 ms steps of the linearly implicit Euler solver (one
    evaluation and one 13 x 13 Cholesky solve per step). Against adaptive ROS34PW2
    at rtol 1e-4 over the first second at 4 N (benchmarks/grasp_peers.py) the ball's
    lift and slip differ by 0.09 and 0.01 mm (4 ms steps: 0.56 and 0.30 mm); over
    the 1.8 s of ``main`` the slow creep of the held ball (2.72 mm with Tsit5 at rtol
    1e-4) comes out 2.48 mm (1 ms steps: 2.59 mm, 4 ms: 2.02 mm; the error is first
    order in the step). ``dt=None`` takes adaptive steps of ``solver`` at ``rtol``,
    ``atol`` (e.g. ``solver="ros34pw2"``).
    """
    # the tension as an array argument: every tension runs the same program
    u = eqx.Partial(inputs, tension=jnp.asarray(tension))
    steps = dict(rtol=rtol, atol=atol) if dt is None else dict(dt0=dt)
    # the ball's heights' program compiles in a worker thread beside the simulation's
    ball_heights.compile_ahead(lk, np.zeros((n_save, lk.n_dof)))
    tr = sj.simulate(lk, t1, u=u, solver=solver, n_save=n_save,
                     max_steps=200_000, **steps)  # fmt: skip
    return tr, np.asarray(ball_heights(lk, tr.q)), np.asarray(tr.q[:, 0])


@sj.jit
def ball_heights(lk, q):
    """The ball's centre height [m] at each row of ``q`` (one compiled program)."""
    cm = lk.layout.links[3].cm_point
    return jax.vmap(lambda q_: sj.forward_kinematics(lk, q_)[cm, 2, 3])(q)


def slip(lk, tension, t1, adjoint=None, throw=True, dt=5e-4):
    """How far the ball fell behind the palm between the lift's start and ``t1`` [m].

    A JAX scalar, differentiable in ``tension`` (give ``adjoint``, e.g.
    ``diffrax.ForwardMode()``, for ``jax.jvp``): the palm's rise minus the ball's,
    from t = 0.4 s (the lift begins) to ``t1``, the ball's height taken at its
    centre of mass by ``sj.forward_kinematics``; ``throw=False`` under ``vmap``
    (a failed rollout gives NaN or a truncated trajectory instead of an error).
    Constant steps of ``dt`` (linearly implicit Euler): a smooth function of the
    tension, every rollout of a ``vmap`` in lockstep; ``dt=None``: adaptive Tsit5
    at rtol 1e-4.
    """
    u = eqx.Partial(inputs, tension=jnp.asarray(tension))
    if dt is None:
        steps = dict(solver="tsit5", rtol=1e-4, atol=1e-7, max_steps=200_000)
    else:
        steps = dict(solver="rosenbrock_euler", dt0=dt,
                     max_steps=int(np.ceil(t1 / dt)) + 1)  # fmt: skip
    tr = sj.simulate(lk, t1, u=u, ts=jnp.array([0.4, t1]), adjoint=adjoint,
                     throw=throw, **steps)  # fmt: skip
    cm = lk.layout.links[3].cm_point
    ball = jax.vmap(lambda q: sj.forward_kinematics(lk, q)[cm, 2, 3])(tr.q)
    return (tr.q[-1, 0] - tr.q[0, 0]) - (ball[-1] - ball[0])


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--out", default=".")
    p.add_argument("--tensions", type=float, nargs="+", default=[2.0, 4.0])
    p.add_argument("--t1", type=float, default=1.8)
    p.add_argument("--overwrite", action="store_true")
    a = p.parse_args(argv)
    out = pathlib.Path(a.out) / "grasp.png"
    if out.exists() and not a.overwrite:
        sys.exit(f"{out} exists: give --overwrite to replace it.")
    sj.enable_compilation_cache()
    lk = gripper()
    results = {}
    for T in a.tensions:
        t0 = time.perf_counter()
        tr, ball, palm = grasp(lk, T, a.t1)
        # slip: how far the ball fell behind the palm since the lift began
        slip = (palm[-1] - palm[0]) - (ball[-1] - ball[np.searchsorted(tr.t, 0.4)])
        results[T] = (tr, ball, palm, slip)
        print(f"T = {T:.1f} N: ball lifted {(ball[-1] - ball[0]) * 1e3:.1f} mm of "
              f"{LIFT * 1e3:.0f}, slipped {slip * 1e3:.1f} mm, {int(tr.num_steps)} "
              f"steps, {time.perf_counter() - t0:.1f} s")  # fmt: skip
    _figure(out, results)
    print(f"wrote {out}")
    return results


def _figure(out, results):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 2, figsize=(11, 4))
    for T, (tr, ball, palm, _) in results.items():
        t = np.asarray(tr.t)
        (line,) = ax[0].plot(t, ball * 1e3, label=f"ball, T = {T:g} N")
        ax[0].plot(t, (palm + ball[0]) * 1e3, "--", color=line.get_color(), lw=0.8)
        cs = tr.contact
        rows = np.where(np.asarray(cs.obstacle) < 0)[0]  # the pairs' rows
        f = np.asarray(cs.force)[:, rows]
        # the pairs' rows are forces on the ball from finger 2, then finger 3
        n = len(rows) // 2
        for k, sl in enumerate((slice(0, n), slice(n, None)), start=1):
            mag = np.linalg.norm(np.sum(f[:, sl], axis=1), axis=-1)
            ax[1].plot(t, mag, color=line.get_color(), ls="-" if k == 1 else ":",
                       label=f"finger {k}, T = {T:g} N")  # fmt: skip
    ax[0].set(xlabel="t [s]", ylabel="height [mm]",
              title="ball (solid) and palm + start (dashed)")  # fmt: skip
    ax[0].legend()
    ax[1].set(xlabel="t [s]", ylabel="contact force on the ball [N]",
              title="each finger's resultant on the ball")  # fmt: skip
    ax[1].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    main()
