"""Actuated and closed-chain scenes: a four-cable soft manipulator and two mechanisms.

- :func:`cable_manipulator`: a tapered soft arm (two divisions, 0.4 m + 0.5 m)
  hanging under gravity, bent by four cables at 90 degree spacing.
- :func:`four_bar`: a planar crank-rocker of rigid bars, the loop closed by a
  revolute joint between the coupler tip and the rocker tip; the crank angle is
  prescribed. :func:`four_bar_assemble` gives the assembled coordinates for a crank
  angle (circle intersection).
- :func:`slider_crank`: crank, connecting rod and a slider on a prismatic joint
  from the ground, the loop closed by a revolute joint between the rod tip and the
  slider; the crank angle is prescribed. :func:`slider_crank_assemble` gives the
  assembled coordinates and :func:`slider_crank_position` the textbook slider
  formula.

Everything here is built from the public model classes; no solver runs on import or
build. The mechanisms lie in the world x-y plane (revolute axes along z) with gravity
along -y.
"""

import math

import jax
import jax.numpy as jnp
import numpy as np

from .model import (
    Cable,
    CableSpan,
    CircularSection,
    ClosedLoopJoint,
    ConstantPath,
    Division,
    Joint,
    JointActuator,
    LegendreBasis,
    Linkage,
    Material,
    ObliquePath,
    RectangularSection,
    RigidLink,
    SoftLink,
    translation,
)

Z_AXIS = (0.0, 0.0, 1.0)

# ----------------------------------------------------------------- cable manipulator
ARM_LENGTHS = (0.4, 0.5)  # division lengths [m]
ARM_RADII = (0.02, 0.01)  # base and tip radius of the linear taper [m]
CABLE_FRACTION = 0.75  # cable offset as a fraction of the local radius
CABLE_NAMES = ("+y", "+z", "-y", "-z")
"""Cable names: the cross-section direction each cable runs on (local y, z).

The arm hangs along world -z: its local y is world +y and its local z is world +x,
so cable ``+y`` bends the tip toward world +y and cable ``+z`` toward world +x.
"""


def _hanging() -> np.ndarray:
    """Rotation by +90 degrees about y: local x (the rod axis) -> world -z."""
    g = np.eye(4)
    g[:3, :3] = [[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]]
    return g


def cable_manipulator(
    paths: str = "oblique",
    E: float = 1e6,
    eta: float = 0.0,
    rho: float = 1000.0,
    gravity: bool = True,
    order: int = 1,
    torsion: bool = False,
    n_gauss: int | None = None,
    actuator_strength=None,
) -> Linkage:
    """A tapered soft arm hanging from the ground, driven by four cables.

    One soft link, clamped at the world origin and pointing down (world -z), of two
    divisions 0.4 m and 0.5 m long; the circular radius tapers linearly from 2 cm at
    the base to 1 cm at the tip over the whole arm (2 -> 1.556 cm, then 1.556 ->
    1 cm). Material: ``E`` (default 1 MPa), poisson 0.5, ``rho``, Kelvin-Voigt
    damping ``eta`` [Pa s]. Strain: bending about local y and z (plus torsion with
    ``torsion``), Legendre order ``order`` per division: inextensible and shearless
    (8 DoF at the defaults).

    Four cables at 90 degree spacing (local +y, +z, -y, -z, see
    :data:`CABLE_NAMES`), each spanning both divisions from base to tip:

    - ``paths="oblique"``: the offset follows the taper, 0.75 r(X), i.e. from
      1.5 cm at the base to 0.75 cm at the tip (linear in the link-normalised X);
    - ``paths="constant"``: a constant offset of 0.75 cm (inside the tip section).

    The inputs are the four tensions [N] (> 0 pulls), in that order.

    Args:
        paths: ``"oblique"`` or ``"constant"``.
        E: Young's modulus [Pa].
        eta: material damping [Pa s] (the arm settles only with some).
        rho: density [kg/m^3].
        gravity: gravity 9.81 m/s^2 along world -z (along the hanging arm), or none.
        order: Legendre order of the strain in each division.
        torsion: also a torsion mode (4 more DoF at order 1).
        n_gauss: Gauss points per division (default: the library's).
        actuator_strength: optional hook ``(t, q, qd, kin) -> (4,)`` replacing the
            tensions (feedback control).

    Returns:
        The :class:`~sorojax.Linkage` (n_inputs = 4).

    Raises:
        ValueError: unknown ``paths``.
    """
    L1, L2 = ARM_LENGTHS
    r0, r1 = ARM_RADII
    L = L1 + L2
    r_mid = r0 + (r1 - r0) * L1 / L
    modes = (1 if torsion else 0, 1, 1, 0, 0, 0)
    basis = LegendreBasis(modes, order)
    arm = SoftLink(
        [
            Division(L1, CircularSection((r0, r_mid)), basis, n_gauss=n_gauss),
            Division(L2, CircularSection((r_mid, r1)), basis, n_gauss=n_gauss),
        ],
        Material(E=E, poisson=0.5, rho=rho, eta=eta),
        color="tab:orange",
    )
    directions = ((1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0))
    if paths == "oblique":
        d0, d1 = CABLE_FRACTION * r0, CABLE_FRACTION * r1

        def make_path(c, s):
            return ObliquePath(start=(d0 * c, d0 * s), end=(d1 * c, d1 * s))

    elif paths == "constant":
        d = CABLE_FRACTION * r1

        def make_path(c, s):
            return ConstantPath(d * c, d * s)

    else:
        raise ValueError(
            f"cable_manipulator(paths={paths!r}): give 'oblique' or 'constant'."
        )
    cables = [
        Cable(CableSpan(1, make_path(c, s), divisions=(1, 2)), name=name)
        for (c, s), name in zip(directions, CABLE_NAMES, strict=True)
    ]
    return Linkage(
        [arm],
        placements=jnp.asarray(_hanging())[None],
        gravity=(0.0, 0.0, -9.81) if gravity else (0.0, 0.0, 0.0),
        actuators=cables,
        actuator_strength=actuator_strength,
    )


# --------------------------------------------------------------------- mechanisms
BAR_SECTION = 0.02  # square section of every bar [m]
BAR_RHO = 1000.0  # density of every bar [kg/m^3]
FOUR_BAR = {"crank": 0.1, "coupler": 0.4, "rocker": 0.3, "ground": 0.35}
"""Four-bar lengths [m]: crank + coupler < rocker + ground (Grashof), crank shortest."""
SLIDER_CRANK = {"crank": 0.1, "rod": 0.3, "slider": 0.08}
"""Slider-crank lengths [m]: crank radius, connecting rod, slider block length."""


def _bar(length: float, joint: Joint, color: str = "tab:gray") -> RigidLink:
    return RigidLink(
        joint,
        length=length,
        section=RectangularSection(BAR_SECTION, BAR_SECTION),
        rho=BAR_RHO,
        color=color,
    )


def four_bar(gravity: bool = True, prescribed: bool = True) -> Linkage:
    """Planar crank-rocker of rigid bars (lengths :data:`FOUR_BAR`) in the x-y plane.

    Links: 1 crank (revolute about z at the origin), 2 coupler (revolute about z at
    the crank tip, coordinate relative to the crank), 3 rocker (revolute about z at
    the ground pivot (0.35, 0, 0), absolute angle). A closed-loop revolute about z
    joins the coupler tip to the rocker tip. Bars are 2 x 2 cm, rho 1000 kg/m^3.
    q = (crank angle, coupler angle relative to the crank, rocker angle) [rad].

    Args:
        gravity: 9.81 m/s^2 along -y, or none.
        prescribed: the crank angle is the input (``JointActuator(1,
            prescribed=True)``, one input; its torque is the solved effort); False
            leaves the mechanism unactuated.

    Returns:
        The :class:`~sorojax.Linkage` (3 DoF, 5 constraint rows of rank 2).
    """
    a, b, c, d = (FOUR_BAR[k] for k in ("crank", "coupler", "rocker", "ground"))
    rz = Joint("R", axis=Z_AXIS)
    return Linkage(
        [_bar(a, rz, "tab:red"), _bar(b, rz, "tab:blue"), _bar(c, rz, "tab:green")],
        parents=(0, 1, 0),
        placements=jnp.asarray(np.stack([np.eye(4), np.eye(4), translation(d)])),
        gravity=(0.0, -9.81, 0.0) if gravity else (0.0, 0.0, 0.0),
        actuators=[JointActuator(1, prescribed=True)] if prescribed else (),
        closed_loops=[ClosedLoopJoint(Joint("R", axis=Z_AXIS), 2, 3)],
    )


def four_bar_assemble(theta: float, branch: int = 1) -> np.ndarray:
    """Assembled four-bar coordinates for crank angle ``theta`` [rad].

    The coupler-rocker pin is the intersection of the circle of radius ``coupler``
    about the crank tip with the circle of radius ``rocker`` about the ground pivot;
    ``branch = +1`` takes the intersection to the left of the line from the crank tip
    to the ground pivot (the open, upper configuration), ``-1`` the other one.

    Returns:
        q = (theta, coupler angle relative to the crank, rocker angle), float64.

    Raises:
        ValueError: the circles do not meet (cannot happen for a Grashof crank).
    """
    a, b, c, d = (FOUR_BAR[k] for k in ("crank", "coupler", "rocker", "ground"))
    A = np.array([a * math.cos(theta), a * math.sin(theta)])
    D = np.array([d, 0.0])
    AD = D - A
    dist = float(np.hypot(*AD))
    along = (b**2 - c**2 + dist**2) / (2 * dist)  # from A toward D
    h2 = b**2 - along**2
    if h2 < 0:
        raise ValueError(f"four_bar_assemble({theta}): the loop cannot close.")
    e = AD / dist
    n = np.array([-e[1], e[0]])
    P = A + along * e + branch * math.sqrt(h2) * n
    phi = math.atan2(P[1] - A[1], P[0] - A[0])  # coupler, absolute
    psi = math.atan2(P[1] - D[1], P[0] - D[0])  # rocker, absolute
    rel = (phi - theta + math.pi) % (2 * math.pi) - math.pi
    return np.array([theta, rel, psi])


def slider_crank(gravity: bool = True, prescribed: bool = True) -> Linkage:
    """Planar slider-crank (lengths :data:`SLIDER_CRANK`) in the x-y plane.

    Links: 1 crank (revolute about z at the origin), 2 connecting rod (revolute about
    z at the crank tip, coordinate relative to the crank), 3 slider block on a
    prismatic joint along world x from the origin (zero offset: the slide line passes
    through the crank pivot). The block's joint coordinate s is the position of its
    rear face; the pin is at its centre, s + slider / 2. A closed-loop revolute about
    z joins the rod tip to the slider centre (``g_B`` = translation(-slider / 2) from
    the block's tip). q = (crank angle, rod angle relative to the crank, s).

    Args:
        gravity: 9.81 m/s^2 along -y (normal to the slide), or none.
        prescribed: the crank angle is the input (one input; its torque is the
            solved effort); False leaves it unactuated.

    Returns:
        The :class:`~sorojax.Linkage` (3 DoF, 5 constraint rows of rank 2).
    """
    r, l, w = (SLIDER_CRANK[k] for k in ("crank", "rod", "slider"))
    rz = Joint("R", axis=Z_AXIS)
    slide = Joint("P", axis=(1.0, 0.0, 0.0))
    return Linkage(
        [_bar(r, rz, "tab:red"), _bar(l, rz, "tab:blue"), _bar(w, slide, "tab:green")],
        parents=(0, 1, 0),
        gravity=(0.0, -9.81, 0.0) if gravity else (0.0, 0.0, 0.0),
        actuators=[JointActuator(1, prescribed=True)] if prescribed else (),
        closed_loops=[
            ClosedLoopJoint(Joint("R", axis=Z_AXIS), 2, 3, g_B=translation(-w / 2))
        ],
    )


def slider_crank_position(theta):
    """Pin position along the slide for crank angle ``theta``: the textbook formula.

    ``x = r cos(theta) + sqrt(l^2 - r^2 sin(theta)^2)`` (zero offset). Works on
    NumPy and JAX arrays.
    """
    r, l = SLIDER_CRANK["crank"], SLIDER_CRANK["rod"]
    xp = jnp if isinstance(theta, jax.Array) else np
    return r * xp.cos(theta) + xp.sqrt(l**2 - (r * xp.sin(theta)) ** 2)


def slider_crank_assemble(theta: float) -> np.ndarray:
    """Assembled slider-crank coordinates for crank angle ``theta`` [rad].

    Returns:
        q = (theta, rod angle relative to the crank, slider coordinate s), with the
        rod's absolute angle ``-asin(r sin(theta) / l)`` and ``s = x - slider / 2``.
    """
    r, l, w = (SLIDER_CRANK[k] for k in ("crank", "rod", "slider"))
    phi = -math.asin(r * math.sin(theta) / l)
    rel = (phi - theta + math.pi) % (2 * math.pi) - math.pi
    x = float(slider_crank_position(float(theta)))
    return np.array([theta, rel, x - w / 2])
