"""Contact in plots and animations (Agg backend): obstacles and contact-force arrows.

The scene: a soft rod of radius 1 cm and length 0.3 m on a vertical prismatic joint,
its axis 1 cm above a floor (``Plane()``), resting on it under gravity at the
statics solution; a sphere and a box stand nearby, not touching it.
"""

import matplotlib

matplotlib.use("Agg")

import math  # noqa: E402

import jax.numpy as jnp  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from mpl_toolkits.mplot3d import art3d  # noqa: E402
from PIL import Image  # noqa: E402

import sorojax  # noqa: E402
from sorojax.model import Box, Contact, ContactLaw, Plane, Sphere  # noqa: E402
from sorojax.viz import animate, plotq  # noqa: E402

N_CIRCLE = 12
RADIUS, LENGTH, RHO, G = 0.01, 0.3, 1000.0, 9.81
SPHERE_RADIUS, SPHERE_CENTRE = 0.02, np.array([0.1, 0.1, 0.05])
BOX_HALF = np.array([0.02, 0.02, 0.02])
_c, _s = math.cos(math.pi / 6), math.sin(math.pi / 6)
BOX_POSE = np.array(  # turned 30 degrees about z, resting on the floor
    [[_c, -_s, 0.0, 0.2], [_s, _c, 0.0, -0.1], [0.0, 0.0, 1.0, 0.02], [0, 0, 0, 1]]
)


def _sphere_motion(t):
    """The sphere slides along -y at 0.1 m/s."""
    return jnp.eye(4).at[1, 3].set(-0.1 * t)


def _scene(moving_sphere: bool = False):
    rod = sorojax.SoftLink(
        sorojax.Division(
            LENGTH,
            sorojax.CircularSection(RADIUS),
            sorojax.LegendreBasis((0, 1, 1, 0, 0, 0), 1),
        ),
        sorojax.Material(E=1e6, poisson=0.5, rho=RHO),
        joint=sorojax.Joint("P", axis=(0.0, 0.0, 1.0)),
    )
    placement = np.eye(4)
    placement[2, 3] = RADIUS
    sphere = Sphere(
        SPHERE_RADIUS,
        centre=SPHERE_CENTRE,
        motion=_sphere_motion if moving_sphere else None,
    )
    contact = Contact(
        [Plane(), sphere, Box(BOX_HALF, pose=BOX_POSE)],
        ContactLaw(stiffness=1e4),
        spacing=0.05,
    )
    return sorojax.Linkage(
        rod, placements=placement[None], gravity=(0.0, 0.0, -G), contact=contact
    )


@pytest.fixture(scope="module")
def rest():
    """The scene, its equilibrium on the floor and the contact state there."""
    lk = _scene()
    q = np.asarray(sorojax.solve_statics(lk).q)
    return lk, q, sorojax.contact_state(lk, q)


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


def _by_gid(ax, prefix):
    return {
        a.get_gid(): a for a in ax.collections if (a.get_gid() or "").startswith(prefix)
    }


def _scene_extent(ax) -> float:
    """Largest extent of the rod's tube and the sphere's and box's bounds (the rule
    that sizes the floor's square and the default force arrows)."""
    tube = _by_gid(ax, "sorojax-link1")["sorojax-link1-division1"]
    box = _by_gid(ax, "sorojax-obstacle2")["sorojax-obstacle2"]
    pts = np.concatenate(
        [
            tube.sorojax_rings.reshape(-1, 3),
            [SPHERE_CENTRE - SPHERE_RADIUS, SPHERE_CENTRE + SPHERE_RADIUS],
            box.sorojax_points,
        ]
    )
    return float(np.ptp(pts, axis=0).max())


def test_obstacles_are_drawn_with_their_geometry(rest, tmp_path):
    lk, q, _ = rest
    fig, ax = plotq(lk, q, n_circle=N_CIRCLE)
    obs = _by_gid(ax, "sorojax-obstacle")
    assert set(obs) == {f"sorojax-obstacle{k}" for k in range(3)}, set(obs)
    plane, sphere, box = (obs[f"sorojax-obstacle{k}"] for k in range(3))
    assert [a.sorojax_kind for a in (plane, sphere, box)] == ["plane", "sphere", "box"]
    assert isinstance(plane, art3d.Poly3DCollection)
    assert isinstance(sphere, art3d.Poly3DCollection)
    assert isinstance(box, art3d.Line3DCollection)

    # Floor: a square in z = 0 of side the scene's largest extent, under the rod
    # (rounding-level tolerances: the corners are sums of a few products).
    corners = plane.sorojax_points
    np.testing.assert_allclose(corners[:, 2], 0.0, atol=1e-15, err_msg="floor z")
    sides = np.linalg.norm(np.roll(corners, -1, axis=0) - corners, axis=1)
    np.testing.assert_allclose(sides, _scene_extent(ax), rtol=1e-12, err_msg="side")
    np.testing.assert_allclose(
        np.linalg.norm(corners[0] - corners[2]), math.sqrt(2) * sides[0], rtol=1e-12
    )
    tube = _by_gid(ax, "sorojax-link1")["sorojax-link1-division1"]
    lo, hi = corners.min(axis=0), corners.max(axis=0)
    assert np.all(tube.sorojax_centres[:, :2] >= lo[:2]), "rod outside the floor"
    assert np.all(tube.sorojax_centres[:, :2] <= hi[:2]), "rod outside the floor"

    # Sphere: every surface point at the radius from the centre.
    d = np.linalg.norm(sphere.sorojax_points - SPHERE_CENTRE, axis=-1)
    np.testing.assert_allclose(d, SPHERE_RADIUS, atol=1e-15, err_msg="sphere radius")
    assert sphere.sorojax_points.shape[1] == N_CIRCLE

    # Box: its 8 corners at the pose, 12 edges of the box's side lengths.
    local = (box.sorojax_points - BOX_POSE[:3, 3]) @ BOX_POSE[:3, :3]
    np.testing.assert_allclose(np.abs(local), np.tile(BOX_HALF, (8, 1)), atol=1e-15)
    fig.canvas.draw()
    assert len(box.get_segments()) == 12, "box edges"

    # The limits hold the obstacles.
    top = SPHERE_CENTRE + [0.0, 0.0, SPHERE_RADIUS]
    for p in (top, *box.sorojax_points):
        for lim, x in zip(
            (ax.get_xlim(), ax.get_ylim(), ax.get_zlim()), p, strict=True
        ):
            assert lim[0] <= x <= lim[1], (p, lim)
    path = tmp_path / "contact.png"
    fig.savefig(path)
    assert path.stat().st_size > 1000

    _, ax2 = plotq(lk, q, obstacles=False)
    assert not _by_gid(ax2, "sorojax-obstacle")


def test_contact_force_arrows_at_the_active_contacts(rest):
    lk, q, cs = rest
    active = np.asarray(cs.active)
    n_active = int(active.sum())
    assert 2 <= n_active < len(active), f"{n_active} active contacts of {len(active)}"
    fig, ax = plotq(lk, q, n_circle=N_CIRCLE, contact_forces=True)
    arrows = [c for c in ax.collections if c.get_gid() == "sorojax-contact-forces"]
    assert len(arrows) == 1
    qv = arrows[0]
    np.testing.assert_array_equal(qv.sorojax_origins, np.asarray(cs.point)[active])
    np.testing.assert_array_equal(qv.sorojax_forces, np.asarray(cs.force)[active])
    np.testing.assert_allclose(qv.sorojax_vectors, qv.sorojax_scale * qv.sorojax_forces)
    fig.canvas.draw()
    assert len(qv.get_segments()) == 3 * n_active, "a shaft and two head lines each"
    # Default scale: the largest arrow is 20 % of the scene's largest extent.
    longest = np.linalg.norm(qv.sorojax_vectors, axis=1).max()
    np.testing.assert_allclose(longest, 0.2 * _scene_extent(ax), rtol=1e-12)
    # The floor carries the rod's weight (the joint slides freely along z); the
    # statics residual tolerance (1e-10) bounds the error far below 1e-6.
    weight = RHO * math.pi * RADIUS**2 * LENGTH * G
    np.testing.assert_allclose(
        qv.sorojax_forces.sum(axis=0), [0.0, 0.0, weight], rtol=1e-6, atol=1e-9
    )

    _, ax2 = plotq(lk, q, contact_forces=0.05)
    qv2 = _by_gid(ax2, "sorojax-contact-forces")["sorojax-contact-forces"]
    np.testing.assert_allclose(qv2.sorojax_vectors, 0.05 * qv.sorojax_forces)
    _, ax3 = plotq(lk, q)
    assert not _by_gid(ax3, "sorojax-contact-forces")

    with pytest.raises(ValueError, match="contact_forces"):
        plotq(lk, q, contact_forces=-1.0)
    bare = sorojax.Linkage(lk.links, placements=lk.placements, gravity=lk.gravity)
    with pytest.raises(ValueError, match="no contact"):
        plotq(bare, q, contact_forces=True)


def test_moving_obstacle_drawn_at_time_t_and_animated(rest, tmp_path):
    """A sliding sphere is drawn where its motion puts it at ``t``; a video of the
    resting rod with the moving sphere and the contact forces has one frame per
    ``1 / fps`` of simulated time."""
    _, q, _ = rest
    lk = _scene(moving_sphere=True)
    _, ax = plotq(lk, q, n_circle=N_CIRCLE, t=0.5)
    sphere = _by_gid(ax, "sorojax-obstacle1")["sorojax-obstacle1"]
    np.testing.assert_allclose(sphere.sorojax_pose, np.asarray(_sphere_motion(0.5)))
    d = np.linalg.norm(sphere.sorojax_points - (SPHERE_CENTRE - [0, 0.05, 0]), axis=-1)
    np.testing.assert_allclose(d, SPHERE_RADIUS, atol=1e-15, err_msg="moved sphere")

    t = jnp.linspace(0.0, 0.2, 3)
    traj = sorojax.Trajectory(
        t=t,
        q=jnp.tile(jnp.asarray(q), (3, 1)),
        qd=jnp.zeros((3, lk.n_dof)),
        result=sorojax.RESULTS.successful,
        num_steps=jnp.asarray(2),
        num_accepted_steps=jnp.asarray(2),
        num_rejected_steps=jnp.asarray(0),
    )
    out = animate(
        lk,
        traj,
        tmp_path / "contact.gif",
        fps=10,
        figsize=(2.0, 2.0),
        dpi=50,
        n_circle=6,
        n_sub=1,
        contact_forces=True,
    )
    with Image.open(out) as im:
        assert im.n_frames == 3
    with pytest.raises(TypeError, match="t"):
        animate(lk, traj, tmp_path / "x.gif", t=0.1)
