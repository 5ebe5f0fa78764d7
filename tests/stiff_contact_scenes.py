"""Three contact statics scenes for any penalty stiffness (tests and benchmarks).

Each builder takes the law's stiffness (an array, so that one compiled solve serves
every stiffness) and returns a linkage whose statics starts from the reference
shape, out of contact:

- :func:`cantilever_on_floor`: a heavy soft cantilever (1 m, r 1 cm, E 1 MPa, rho
  1000, bending only, 8 divisions of order 4) clamped level 0.15 m above a
  frictionless floor; most of it comes to lie on the floor (k per length, N/m^2).
- :func:`rod_over_sphere`: a planar cantilever (1 m, r 1 cm, E 10 MPa, 4 divisions
  of order 3) clamped 0.1 m up, whose weight lays it over a sphere of radius 0.1 m
  under its middle (k per length, N/m^2).
- :func:`crossing_rods`: two cantilevers crossing at right angles, the upper (E 100
  MPa) 5 cm above the stiffer lower one (E 1 GPa), each with two bending modes (4
  divisions of order 3): the upper falls onto the lower and presses on it at one
  point (a rod pair, k per point, N/m).
- :func:`ball_in_tube`: a 5 g ball (radius 8 mm, on a vertical prismatic joint) in
  the middle of a soft horizontal tube (0.3 m, bore radius 1 cm, E 1 MPa, two
  bending modes of order 2) that sags under its own weight: the ball comes to rest
  on the bore (a tube, k per point, N/m).
"""

import jax.numpy as jnp
import numpy as np

import sorojax as sj

G = 9.81
SMOOTHING = 1e-8  # m: far below the penetrations of the stiffest law tried


def _rod(n, order, E, modes, r=0.01, rho=1000.0, length=1.0):
    div = sj.Division(length / n, sj.CircularSection(r), sj.LegendreBasis(modes, order))
    return sj.SoftLink([div] * n, sj.Material(E=E, poisson=0.5, rho=rho))


def _placed(x=0.0, y=0.0, z=0.0, R=None):
    g = np.eye(4)
    if R is not None:
        g[:3, :3] = R
    g[:3, 3] = (x, y, z)
    return g


WEIGHT = 1000.0 * np.pi * 0.01**2 * G  # N/m: the weight per length of the rods


def barrier_law(reach, force=WEIGHT) -> sj.ContactLaw:
    """A barrier of ``reach`` [m] whose force scale ``k reach`` is ``force`` [N/m]."""
    reach = jnp.asarray(reach, float)
    return sj.ContactLaw(stiffness=force / reach, smoothing=reach, kind="barrier")


def cantilever_on_floor(k, E=1e6, rho=1000.0, floor_z=0.0, law=None) -> sj.Linkage:
    """``law``: another contact law (then ``k`` is not used)."""
    rod = _rod(8, 4, E, (0, 1, 0, 0, 0, 0), rho=rho)
    floor = sj.Plane(point=jnp.stack([0.0, 0.0, jnp.asarray(floor_z, float)]))
    law = sj.ContactLaw(stiffness=k, smoothing=SMOOTHING) if law is None else law
    return sj.Linkage(
        [rod], placements=_placed(z=0.15)[None], gravity=(0, 0, -G),
        contact=sj.Contact(floor, law),
    )  # fmt: skip


def rod_over_sphere(k, E=1e7, rho=1000.0, sphere_z=-0.01, law=None) -> sj.Linkage:
    """``law``: another contact law (then ``k`` is not used)."""
    rod = _rod(4, 3, E, (0, 1, 0, 0, 0, 0), rho=rho)
    pose = jnp.eye(4).at[:3, 3].set(jnp.stack([0.5, 0.0, jnp.asarray(sphere_z, float)]))
    law = sj.ContactLaw(stiffness=k, smoothing=SMOOTHING) if law is None else law
    return sj.Linkage(
        [rod], placements=_placed(z=0.1)[None], gravity=(0, 0, -G),
        contact=sj.Contact(sj.Sphere(0.1, pose=pose), law),
    )  # fmt: skip


def crossing_rods(k, E=1e8, rho=1000.0, drop=0.0) -> sj.Linkage:
    """``drop`` lowers the lower rod's clamp [m] (an obstacle's position)."""
    modes = (0, 1, 1, 0, 0, 0)
    upper = _rod(4, 3, E, modes, rho=rho)
    lower = _rod(4, 3, 1e9, modes)
    turn = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    placements = jnp.stack(
        [
            jnp.asarray(_placed(x=-0.5, z=0.05)),
            jnp.asarray(_placed(y=-0.5, R=turn)).at[2, 3].add(-drop),
        ]
    )
    law = sj.ContactLaw(stiffness=k, smoothing=SMOOTHING)
    return sj.Linkage(
        [upper, lower], parents=(0, 0), placements=placements, gravity=(0, 0, -G),
        contact=sj.Contact((), law, rod_pairs=[(1, 2)]),
    )  # fmt: skip


BALL_MASS = 0.005  # kg


def ball_in_tube(k, E=1e6, rho=1000.0, height=0.0) -> sj.Linkage:
    """``height`` raises the ball's joint [m] (an obstacle's position)."""
    tube = sj.SoftLink(
        [sj.Division(0.3, sj.AnnularSection(0.014, 0.01),
                     sj.LegendreBasis((0, 1, 1, 0, 0, 0), 2))],
        sj.Material(E=E, poisson=0.5, rho=rho),
    )  # fmt: skip
    ball = sj.RigidLink(
        sj.Joint("P", axis=(0, 0, 1)), length=0.01, mass=BALL_MASS,
        inertia=np.diag([1e-7] * 3), g_i=np.eye(4), g_f=np.eye(4),
    )  # fmt: skip
    placements = jnp.stack(
        [jnp.eye(4), jnp.asarray(_placed(x=0.15)).at[2, 3].add(height)]
    )
    law = sj.ContactLaw(stiffness=k, smoothing=SMOOTHING)
    return sj.Linkage(
        [tube, ball], parents=(0, 0), placements=placements, gravity=(0, 0, -G),
        contact=sj.Contact((), law, shapes={2: sj.ContactSphere(0.008)},
                           inside=[(1, 2)], spacing=0.01),
    )  # fmt: skip


SCENES = {
    "cantilever_on_floor": cantilever_on_floor,
    "rod_over_sphere": rod_over_sphere,
    "crossing_rods": crossing_rods,
    "ball_in_tube": ball_in_tube,
}
"""name: builder(k, ...)."""


def centre_line(linkage: sj.Linkage, q) -> np.ndarray:
    """World positions of every significant point ``(n_points, 3)`` [m]."""
    return np.asarray(sj.forward_kinematics(linkage, q)[:, :3, 3])
