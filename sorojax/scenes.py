"""Built-in scenes: small, ready-made linkages for demos, tests and benchmarks."""

import math

import jax.numpy as jnp
import numpy as np

from .model import (
    CircularSection,
    Division,
    Joint,
    LegendreBasis,
    Linkage,
    Material,
    PointWrench,
    RectangularSection,
    RigidLink,
    SoftLink,
)


def rotation_y(angle: float) -> np.ndarray:
    """Pose rotating by ``angle`` [rad] about y."""
    c, s = math.cos(angle), math.sin(angle)
    g = np.eye(4)
    g[:3, :3] = [[c, 0, s], [0, 1, 0], [-s, 0, c]]
    return g


def demo_linkage() -> Linkage:
    """The manual's first steps, open-chain part: rigid link + two-division soft link.

    Link 1: rigid 0.3 m bar (4 x 4 cm, rho 1000) on a revolute joint about z with
    stiffness 20 N m/rad. Link 2: soft rod (E 5 MPa, nu 0.5, rho 1000) on the tip of
    link 1, turned +15 degrees about y; division 1 is 0.3 m, radius 2 -> 1.5 cm,
    bending about y and z with linear strain (order 1); division 2 is 0.2 m, radius
    1.5 -> 1 cm, bending about y and z, constant strain (order 0). Gravity along -y;
    a 0.5 N follower force along local y at the end of division 2. ndof = 1 + 4 + 2.
    """
    bend = (0, 1, 1, 0, 0, 0)
    link1 = RigidLink(
        Joint("R", axis=(0.0, 0.0, 1.0), stiffness=20.0),
        length=0.3,
        section=RectangularSection(0.04, 0.04),
        rho=1000.0,
    )
    link2 = SoftLink(
        [
            Division(0.3, CircularSection((0.02, 0.015)), LegendreBasis(bend, 1)),
            Division(0.2, CircularSection((0.015, 0.01)), LegendreBasis(bend, 0)),
        ],
        Material(E=5e6, poisson=0.5, rho=1000.0, eta=1e4),
        joint=Joint("N"),
        color="tab:orange",
    )
    placements = jnp.stack([jnp.eye(4), jnp.asarray(rotation_y(math.radians(15)))])
    return Linkage(
        [link1, link2],
        parents=(0, 1),
        placements=placements,
        gravity=(0.0, -9.81, 0.0),
        point_wrenches=[
            PointWrench(2, [0, 0, 0, 0, 0.5, 0], division=2, X1=1.0, follower=True)
        ],
    )


def cantilever(
    length: float = 1.0,
    radius: float = 0.01,
    E: float = 1e7,
    modes=(0, 1, 1, 0, 0, 0),
    order: int = 4,
    n_divisions: int = 1,
    rho: float = 1000.0,
    gravity=(0.0, 0.0, 0.0),
    tip_wrench=None,
    n_gauss: int | None = None,
) -> Linkage:
    """A clamped straight rod along x (optionally with a world-frame tip wrench)."""
    basis = LegendreBasis(modes, order)
    divs = [
        Division(length / n_divisions, CircularSection(radius), basis, n_gauss=n_gauss)
        for _ in range(n_divisions)
    ]
    rod = SoftLink(divs, Material(E=E, poisson=0.5, rho=rho))
    pws = () if tip_wrench is None else (PointWrench(1, tip_wrench),)
    return Linkage([rod], gravity=gravity, point_wrenches=pws)


def free_fall_rod(
    order: int = 3,
    eta: float = 0.0,
    modes=(1, 1, 1, 0, 0, 0),
    n_gauss: int | None = None,
    E: float = 1e6,
) -> Linkage:
    """SoRoSim's dynamics tutorial rod: clamped at its base, falling under gravity.

    L 0.5 m along x, circular radius tapering linearly 2 -> 1 cm, E 1 MPa, poisson
    0.5, rho 1000 kg/m^3, material damping ``eta`` [Pa s]; torsion and both bendings
    (``modes``) with Legendre order ``order`` (cubic: 12 DoF); gravity 9.81 m/s^2 along
    -z. Start it from :func:`free_fall_q0` (pre-bent 1 rad/m about y) at rest.
    """
    div = Division(
        0.5,
        CircularSection((0.02, 0.01)),
        LegendreBasis(modes, order),
        n_gauss=n_gauss,
    )
    rod = SoftLink([div], Material(E=E, poisson=0.5, rho=1000.0, eta=eta))
    return Linkage([rod], gravity=(0.0, 0.0, -9.81))


def free_fall_q0(linkage: Linkage):
    """Initial coordinates of :func:`free_fall_rod`: uniform bending 1 rad/m about y."""
    from .kinematics import strain_coordinates

    return strain_coordinates(linkage, [0.0, 1.0, 0.0, 0.0, 0.0, 0.0])
