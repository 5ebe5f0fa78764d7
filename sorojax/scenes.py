"""Built-in scenes: small, ready-made linkages for demos, tests and benchmarks."""

import math

import jax.numpy as jnp
import numpy as np

from .model import (
    AbstractSection,
    Cable,
    CableAnchor,
    CableSpan,
    CircularSection,
    ClosedLoopJoint,
    Division,
    Joint,
    JointActuator,
    LegendreBasis,
    Linkage,
    Material,
    ObliquePath,
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
    placements = jnp.asarray(np.stack([np.eye(4), rotation_y(math.radians(15))]))
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
    -z; SoRoSim's section model (no shear correction, as the tutorial and the peer
    comparisons in benchmarks/peers.py). Start it from :func:`free_fall_q0` (pre-bent
    1 rad/m about y) at rest.
    """
    div = Division(
        0.5,
        CircularSection((0.02, 0.01), shear_coefficient=1.0),
        LegendreBasis(modes, order),
        n_gauss=n_gauss,
    )
    rod = SoftLink([div], Material(E=E, poisson=0.5, rho=1000.0, eta=eta))
    return Linkage([rod], gravity=(0.0, 0.0, -9.81))


def free_fall_q0(linkage: Linkage):
    """Initial coordinates of :func:`free_fall_rod`: uniform bending 1 rad/m about y."""
    from .kinematics import strain_coordinates

    return strain_coordinates(linkage, [0.0, 1.0, 0.0, 0.0, 0.0, 0.0])


def rotation_z(angle: float) -> np.ndarray:
    """Pose rotating by ``angle`` [rad] about z."""
    c, s = math.cos(angle), math.sin(angle)
    g = np.eye(4)
    g[:2, :2] = [[c, -s], [s, c]]
    return g


def manual_hybrid(E: float = 2e7, eta: float = 1e4) -> Linkage:
    """The SoRoSim manual's hybrid closed-chain example (section 3), five links.

    Links 1 and 2 and all loads are the manual's: link 1 is a rigid 0.3 m bar (4 x 4
    cm, rho 1000) on a revolute joint about z at the origin; link 2 is a soft rod on
    link 1's tip, turned +15 degrees about y, with two divisions (0.3 m, radius 2 ->
    1.5 cm, bending about y and z, linear strain; 0.2 m, radius 1.5 -> 1 cm, bending
    about y and z, constant strain). Gravity along -y; a 5 N follower force along
    local y at the end of division 2 of link 5; a fixed closed-loop joint between
    the tips of links 4 and 5. Actuators (input ``u = (angle [rad], tension [N])``):
    the revolute joint of link 1 by prescribed coordinate, and one cable (tension
    > 0 pulls) on an oblique path, 12 -> 6 mm off the centre line along local y in
    link 2, continuing 6 -> 4 mm through link 4.

    The manual does not give links 3-5; here (our choice) they close a triangular
    loop on the tip of link 2: link 3 is a rigid 0.15 m cross bar (2 x 2 cm, fixed
    joint) along link 2's tip y axis; link 4 (soft, one division, linear strain)
    starts at link 2's tip and link 5 (soft, two divisions with the orders of link
    2) at link 3's tip; both are 1 cm radius rods aimed at the common point 0.2 m
    ahead of the middle of the bar, so that their tips meet. The closed-loop frame
    on link 4's tip is turned by ``-2 atan(0.075 / 0.2)`` about z, link 5's tip
    orientation at q = 0, so q = 0 is assembled (straight rods; start solves there).
    Links 2, 4 and 5 share the material: ``E`` [Pa] (default 20 MPa, stiffer than the
    first-steps rod of :func:`demo_linkage` so that the 5 N force leaves a moderate
    deflection), poisson 0.5, rho 1000, damping ``eta`` [Pa s]. 17 DoF, 6 constraint
    rows.
    """
    bend = (0, 1, 1, 0, 0, 0)
    material = Material(E=E, poisson=0.5, rho=1000.0, eta=eta)
    link1 = RigidLink(
        Joint("R", axis=(0.0, 0.0, 1.0)),
        length=0.3,
        section=RectangularSection(0.04, 0.04),
        rho=1000.0,
    )
    link2 = SoftLink(
        [
            Division(0.3, CircularSection((0.02, 0.015)), LegendreBasis(bend, 1)),
            Division(0.2, CircularSection((0.015, 0.01)), LegendreBasis(bend, 0)),
        ],
        material,
        color="tab:orange",
    )
    bar, reach = 0.15, 0.2
    side = math.hypot(reach, bar / 2)
    angle = math.atan2(bar / 2, reach)
    link3 = RigidLink(
        Joint("N"), length=bar, section=RectangularSection(0.02, 0.02), rho=1000.0
    )
    link4 = SoftLink(
        Division(side, CircularSection(0.01), LegendreBasis(bend, 1)),
        material,
        color="tab:green",
    )
    link5 = SoftLink(
        [
            Division(side / 2, CircularSection(0.01), LegendreBasis(bend, 1)),
            Division(side / 2, CircularSection(0.01), LegendreBasis(bend, 0)),
        ],
        material,
        color="tab:purple",
    )
    placements = np.stack(
        [
            np.eye(4),
            rotation_y(math.radians(15)),
            rotation_z(math.pi / 2),
            rotation_z(angle),
            rotation_z(-math.pi / 2 - angle),
        ]
    )
    cable = Cable(
        [
            CableSpan(2, ObliquePath((0.012, 0.0), (0.006, 0.0))),
            CableSpan(4, ObliquePath((0.006, 0.0), (0.004, 0.0))),
        ],
        name="cable",
    )
    return Linkage(
        [link1, link2, link3, link4, link5],
        parents=(0, 1, 2, 2, 3),
        placements=jnp.asarray(placements),
        gravity=(0.0, -9.81, 0.0),
        point_wrenches=[
            PointWrench(5, [0, 0, 0, 0, 5.0, 0], division=2, X1=1.0, follower=True)
        ],
        actuators=[JointActuator(1, prescribed=True), cable],
        closed_loops=[
            ClosedLoopJoint("N", link_A=5, link_B=4, g_B=rotation_z(-2 * angle))
        ],
    )


MANUAL_HYBRID_TENSION = 50.0
"""The manual hybrid scene's cable tension [N] (statics; end of the dynamics' ramp)."""


def manual_hybrid_inputs(t):
    """Inputs of the manual hybrid scene's dynamics at ``t`` (angle, tension).

    The revolute angle pi t / 2 [rad], the tension ramped smoothly to 50 N over the
    first second.
    """
    ramp = 0.5 * (1.0 - jnp.cos(jnp.pi * jnp.minimum(t, 1.0)))
    return jnp.stack([jnp.pi * t / 2, MANUAL_HYBRID_TENSION * ramp])


GRASP_LIFT = 0.05
"""How far the grasp's palm rises [m] (``examples/grasp.py``)."""


def grasp_inputs(t, tension):
    """Inputs of the grasp (``examples/grasp.py``) at ``t``: (height, tension x 2).

    The palm's height [m] (rising ``GRASP_LIFT`` between 0.4 and 0.8 s), then the
    two fingers' tensions [N] (ramped to ``tension`` over 0.3 s).
    """
    close = tension * jnp.clip(t / 0.3, 0.0, 1.0)
    lift = GRASP_LIFT * jnp.clip((t - 0.4) / 0.4, 0.0, 1.0)
    return jnp.stack([lift, close, close])


def gripper_finger(
    E: float = 1e6,
    phalanges=(0.045, 0.03, 0.025),
    hinge_length: float = 0.01,
    cable_offset: float = 0.008,
    gravity=(0.0, -9.81, 0.0),
) -> Linkage:
    """A tendon-driven finger: rigid phalanges joined by short soft hinges.

    Along x from the origin: hinge, phalanx, hinge, phalanx, hinge, phalanx (links 1..6,
    soft and rigid alternating, all fixed joints). Each hinge is a ``hinge_length``
    soft rod of 4 x 15 mm rectangular section (E ``E`` [Pa], poisson 0.5, rho 1100)
    bending about z with constant strain (1 DoF; 3 in all); the phalanges are
    ``phalanges`` [m] long, 12 x 15 mm, rho 1100. One tendon (input: tension [N],
    > 0 pulls) runs outside the body on the palm side (local -y): from a ground
    pulley at (-5 mm, -``cable_offset``, 0) through two eyelets per phalanx, 3 mm in
    from each end at ``cable_offset`` below its axis, ending at the last eyelet.
    Pulling shortens the segments across the hinges and curls the finger toward -y.
    Gravity along -y by default (palm down).
    """
    material = Material(E=E, poisson=0.5, rho=1100.0)
    links: list = []
    route: list = [CableAnchor(0, (-0.005, -cable_offset, 0.0))]
    for length in phalanges:
        links.append(
            SoftLink(
                Division(
                    hinge_length,
                    RectangularSection(0.004, 0.015),
                    LegendreBasis((0, 0, 1, 0, 0, 0), 0),
                ),
                material,
                color="tab:orange",
            )
        )
        links.append(
            RigidLink(
                Joint("N"),
                length=length,
                section=RectangularSection(0.012, 0.015),
                rho=1100.0,
            )
        )
        half = length / 2 - 0.003
        for x in (-half, half):  # eyelets, in the phalanx's CM frame
            route.append(CableAnchor(len(links), (x, -cable_offset, 0.0)))
    return Linkage(links, gravity=gravity, actuators=[Cable(route, name="tendon")])


def finger_curl(linkage: Linkage, q) -> float:
    """Curl of :func:`gripper_finger` [rad]: rotation of the fingertip about -z."""
    from .kinematics import tip_pose

    g = np.asarray(tip_pose(linkage, q))
    return -math.atan2(g[1, 0], g[0, 0])


def l_beam(
    order: int | tuple[int, ...] = 3,
    load: float | None = 2000.0,
    length: float = 1.0,
    radius: float = 0.01,
    E: float = 200e9,
    poisson: float = 0.3,
    rho: float = 7850.0,
    gravity=(0.0, 0.0, 0.0),
    modes=(1, 1, 1, 0, 0, 0),
    section: AbstractSection | None = None,
) -> Linkage:
    """An L-shaped beam clamped at both ends, loaded at the corner (our setup).

    Two equal arms of ``length`` [m], solid circular section of ``radius`` [m] (or
    ``section``), material ``E`` [Pa], ``poisson``, ``rho`` (default steel); by default
    both bend about y and z and twist (inextensible, unshearable: Kirchhoff rods),
    strain ``modes`` with Legendre ``order`` (one, or one per active mode). Arm 1
    runs along x from the clamp at the origin to the corner at (L, 0, 0); arm 2 is
    fixed to arm 1's tip turned 90 degrees about z and runs along y to (L, L, 0),
    where a fixed closed-loop joint ('N') clamps its tip to the ground. A world-frame
    force of ``load`` [N] along -z (out of the plane of the L) acts at the corner
    (``None``: no load point).
    A setup of our own (``examples/l_beam.py``); the SoRoSim paper's L-beam (12.98 cm
    GVS vs 13.27 cm ANSYS, two soft 0.7 m arms under gravity) is
    ``examples/l_beam_sorosim.py``, built with this function.
    """
    material = Material(E=E, poisson=poisson, rho=rho)
    section = CircularSection(radius) if section is None else section
    arms = [
        SoftLink(
            Division(length, section, LegendreBasis(modes, order)),
            material,
            color=color,
        )
        for color in ("tab:blue", "tab:orange")
    ]
    g_clamp = rotation_z(math.pi / 2)
    g_clamp[:2, 3] = [length, length]
    loads = [] if load is None else [PointWrench(1, [0.0, 0.0, 0.0, 0.0, 0.0, -load])]
    return Linkage(
        arms,
        placements=jnp.asarray(np.stack([np.eye(4), rotation_z(math.pi / 2)])),
        gravity=gravity,
        point_wrenches=loads,
        closed_loops=[ClosedLoopJoint("N", link_A=2, link_B=0, g_B=g_clamp)],
    )


# ---------------------------------------------------------------- stability scenes
# Rods of E 1 MPa, radius 5 mm, bending about z only (inextensible, shearless: the
# classical elastica), loaded by a unit of their critical load, so that the
# continuation's load factor reads as P / P_cr.
ELASTICA_E, ELASTICA_RADIUS, ELASTICA_LENGTH = 1e6, 0.005, 0.4


def elastica_bending_stiffness() -> float:
    """E I of the elastica scenes' rods [N m^2]."""
    return ELASTICA_E * math.pi * ELASTICA_RADIUS**4 / 4


def euler_column(order: int = 6) -> Linkage:
    """Clamped-free column under a compressive dead load P_cr = pi^2 EI / (4 L^2).

    A soft rod clamped at the origin along x, bending about z only (Legendre
    ``order``), loaded at its tip by ``(0, 0, 0, -P_cr, 0, 0)`` (global). With
    :func:`sorojax.continuation` the load factor is P / P_cr: the straight column
    bifurcates at 1.
    """
    L = ELASTICA_LENGTH
    P_cr = math.pi**2 * elastica_bending_stiffness() / (4 * L**2)
    rod = SoftLink(
        Division(
            L,
            CircularSection(ELASTICA_RADIUS),
            LegendreBasis((0, 0, 1, 0, 0, 0), order),
        ),
        Material(ELASTICA_E),
    )
    return Linkage(rod, point_wrenches=[PointWrench(1, [0.0, 0, 0, -P_cr, 0, 0])])


def pinned_elastica(order: int = 8) -> Linkage:
    """Pinned-pinned column (Euler's elastica) under a dead load P_cr = pi^2 EI / L^2.

    Link 1: the rod on a revolute joint about z at the origin (the fixed pin),
    bending about z only (Legendre ``order``); link 2: a 1 cm, 10 g slider block
    pinned to the rod's tip by a revolute joint about z and kept on the x axis,
    without turning, by a prismatic closed-loop joint along x to the ground (the
    roller). The load ``(0, 0, 0, -P_cr, 0, 0)`` acts on the slider. Coordinate 0
    is the end rotation; with :func:`sorojax.continuation` the load factor is
    P / P_cr (the elastica's end rotation alpha has P / P_cr = (2 K(sin(alpha/2)) /
    pi)^2, e.g. 1.1517 at 60 degrees, Timoshenko & Gere 1961, table 2-7).
    """
    L = ELASTICA_LENGTH
    P_cr = math.pi**2 * elastica_bending_stiffness() / L**2
    z = (0.0, 0.0, 1.0)
    rod = SoftLink(
        Division(
            L,
            CircularSection(ELASTICA_RADIUS),
            LegendreBasis((0, 0, 1, 0, 0, 0), order),
        ),
        Material(ELASTICA_E),
        joint=Joint("R", axis=z),
    )
    block = 0.01
    slider = RigidLink(
        Joint("R", axis=z), length=block, mass=0.01, inertia=np.eye(3) * 1e-6
    )
    back = np.eye(4)
    back[0, 3] = -block  # the slider's joint frame, from its tip frame
    ahead = np.eye(4)
    ahead[0, 3] = L
    return Linkage(
        [rod, slider],
        parents=[0, 1],
        point_wrenches=[PointWrench(2, [0.0, 0, 0, -P_cr, 0, 0])],
        closed_loops=[
            ClosedLoopJoint(Joint("P", axis=(1.0, 0.0, 0.0)), 2, 0, g_A=back, g_B=ahead)
        ],
    )


def von_mises_truss(
    angle: float = math.radians(15.0),
    length: float = 0.3,
    E: float = 1e6,
    load_factor: float = 1.0,
) -> tuple[Linkage, float]:
    """Two extensible bars pinned to the ground and to each other: snap-through.

    Each bar is a soft link of ``length`` (radius 5 mm, stretch mode only, order 0:
    a linear axial spring, exact for a straight bar) on a revolute joint about z;
    bar 1 rises from the origin at ``angle``, bar 2 from ``(2 a, 0)`` mirrored, with
    ``a = length cos(angle)``; their tips are joined by a revolute closed-loop joint
    about z. A downward force ``load_factor F_max`` acts on the apex (bar 1's
    tip), ``F_max``
    the analytic limit load: ``F(y) = -2 E A (l(y)/length - 1) y / l(y)`` with
    ``l(y) = sqrt(a^2 + y^2)`` is the apex force at apex height y, maximal at
    ``y* = sqrt(a^(4/3) length^(2/3) - a^2)``. With :func:`sorojax.continuation` the
    load factor is F / F_max: the symmetric path folds at 1 and at -1.

    Returns:
        ``(linkage, F_max)``.
    """
    a = length * math.cos(angle)
    EA = E * math.pi * ELASTICA_RADIUS**2
    y_star = math.sqrt(a ** (4.0 / 3.0) * length ** (2.0 / 3.0) - a**2)
    l_star = math.hypot(a, y_star)
    F_max = -2.0 * EA * (l_star / length - 1.0) * y_star / l_star
    z = (0.0, 0.0, 1.0)
    bar = SoftLink(
        Division(
            length,
            CircularSection(ELASTICA_RADIUS),
            LegendreBasis((0, 0, 0, 1, 0, 0), 0),
        ),
        Material(E),
        joint=Joint("R", axis=z),
    )
    place2 = rotation_z(math.pi - angle)
    place2[0, 3] = 2 * a
    return (
        Linkage(
            [bar, bar],
            parents=[0, 0],
            placements=[rotation_z(angle), place2],
            point_wrenches=[PointWrench(1, [0.0, 0, 0, 0, -load_factor * F_max, 0])],
            closed_loops=[ClosedLoopJoint(Joint("R", axis=z), 1, 2)],
        ),
        F_max,
    )
