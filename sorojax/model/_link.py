"""Links: a lumped joint at the base followed by a soft or a rigid body.

- :class:`SoftLink`: a Cosserat rod of one or more :class:`Division` s (own length,
  section, strain basis, Gauss points and reference strain each).
- :class:`RigidLink`: a rigid body with its 6x6 spatial inertia at the centre of mass
  (CM), frames ``g_i`` (joint -> CM) and ``g_f`` (CM -> tip). Inertia comes from a
  prismatic shape (length along x, a cross-section) and a density, or is given.

Only primary parameters are stored; derived quantities (section matrices, inertia from
shape, K, D) are computed from them on use, so a changed parameter is never stale.
"""

import abc
from collections.abc import Callable

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from ._basis import AbstractStrainBasis, LegendreBasis
from ._checks import (
    check_finite,
    check_positive,
    check_se3,
    check_shape,
    is_concrete,
)
from ._joint import Joint
from ._material import Material
from ._section import AbstractSection, CircularSection

XI_STRAIGHT = (0.0, 0.0, 0.0, 1.0, 0.0, 0.0)


def _pose(field, g):
    if g is None:
        return jnp.asarray(np.eye(4))  # a transfer, not an operation to compile
    check_se3(field, g)
    return jnp.asarray(g, dtype=float)


def translation(x: float = 0.0, y: float = 0.0, z: float = 0.0) -> Array:
    """Pure translation as a 4x4 pose."""
    if all(isinstance(v, int | float) for v in (x, y, z)):  # no operation to compile
        g = np.eye(4)
        g[:3, 3] = (x, y, z)
        return jnp.asarray(g)
    g = jnp.eye(4)
    return g.at[:3, 3].set(
        jnp.stack(jnp.broadcast_arrays(*map(jnp.asarray, (x, y, z))))
    )


def default_n_gauss(order: int) -> int:
    """Interior points of a division whose basis has order ``order`` by default."""
    return max(8, 2 * order + 4)


class Division(eqx.Module):
    """One division of a soft link.

    Attributes:
        length: division length [m], > 0.
        section: cross-section (profile of X1 in [0, 1] over this division).
        basis: strain basis (active modes and polynomial orders).
        n_gauss: number of interior Gauss-Legendre points (the end points are added
            with zero weight); they bound the Magnus steps, so they set the
            kinematic accuracy (4th order in their spacing; 6th order in linkages
            with a basis of order >= 4). Default
            ``max(8, 2 max_order + 4)``.
        xi_ref: reference (stress-free) strain, a 6-vector or a function of X1
            returning one; default the straight rod (0, 0, 0, 1, 0, 0).
    """

    length: Float[Array, ""]
    section: AbstractSection
    basis: AbstractStrainBasis
    n_gauss: int = eqx.field(static=True)
    xi_ref: Float[Array, "6"] | Callable

    def __init__(
        self,
        length: ArrayLike,
        section: AbstractSection | None = None,
        basis: AbstractStrainBasis | None = None,
        n_gauss: int | None = None,
        xi_ref: ArrayLike | Callable = XI_STRAIGHT,
    ):
        check_positive("Division.length", length)
        if section is None:
            section = CircularSection(0.01)
        if not isinstance(section, AbstractSection):
            raise ValueError(
                f"Division.section = {section!r}: give a CircularSection, "
                "RectangularSection or EllipticalSection."
            )
        if basis is None:
            basis = LegendreBasis()
        if not isinstance(basis, AbstractStrainBasis):
            raise ValueError(
                f"Division.basis = {basis!r}: give a LegendreBasis, MonomialBasis or "
                "CustomBasis."
            )
        if n_gauss is None:
            n_gauss = default_n_gauss(basis.max_order)
        if not isinstance(n_gauss, int | np.integer) or n_gauss < 1:
            raise ValueError(
                f"Division.n_gauss = {n_gauss!r}: give an integer >= 1 (number of "
                "interior Gauss points)."
            )
        if not callable(xi_ref):
            check_shape("Division.xi_ref", xi_ref, (6,))
            check_finite("Division.xi_ref", xi_ref)
            if is_concrete(xi_ref) and not float(np.asarray(xi_ref, float)[3]) > 0:
                raise ValueError(
                    f"Division.xi_ref = {xi_ref!r} has axial stretch gx = "
                    f"{float(np.asarray(xi_ref, float)[3])}: a reference with gx <= 0 "
                    "is a collapsed or inverted rod; give the total reference strain, "
                    "gx = 1 for an unstretched rod, e.g. (0, 1, 0, 1, 0, 0) for a rod "
                    "pre-curved at 1 rad/m about y."
                )
            xi_ref = jnp.asarray(xi_ref, dtype=float)
        self.length = jnp.asarray(length, dtype=float)
        self.section = section
        self.basis = basis
        self.n_gauss = int(n_gauss)
        self.xi_ref = xi_ref

    @property
    def n_dof(self) -> int:
        """Number of strain coordinates of the division."""
        return self.basis.n_dof

    def reference_strain(self, X1) -> Float[Array, "6"]:
        """Reference strain at X1 (physical units: 1/m angular, - linear)."""
        if callable(self.xi_ref):
            out = jnp.asarray(self.xi_ref(jnp.asarray(X1, dtype=float)), dtype=float)
            if out.shape != (6,):
                raise ValueError(
                    f"Division.xi_ref returned shape {out.shape}; expected (6,)."
                )
            return out
        return self.xi_ref


class AbstractLink(eqx.Module):
    """A joint followed by a body."""

    joint: eqx.AbstractVar[Joint]
    g_f: eqx.AbstractVar[Float[Array, "4 4"]]

    @property
    @abc.abstractmethod
    def n_dof(self) -> int:
        """Coordinates of the link (joint + body)."""


class SoftLink(AbstractLink):
    """A Cosserat rod of one or more divisions behind a lumped joint.

    Attributes:
        joint: the lumped joint at the base (default fixed).
        material: material of the rod.
        divisions: tuple of :class:`Division`.
        g_i: pose of the rod start (centre of area) in the joint frame.
        g_f: pose of the tip reference point in the rod's end frame.
        color: plot colour (any matplotlib colour).
    """

    joint: Joint
    material: Material
    divisions: tuple[Division, ...]
    g_i: Float[Array, "4 4"]
    g_f: Float[Array, "4 4"]
    color: str = eqx.field(static=True)

    def __init__(
        self,
        divisions: Division | list | tuple,
        material: Material,
        joint: Joint | None = None,
        g_i: ArrayLike | None = None,
        g_f: ArrayLike | None = None,
        color: str = "tab:blue",
    ):
        if isinstance(divisions, Division):
            divisions = (divisions,)
        divisions = tuple(divisions)
        if len(divisions) == 0 or not all(isinstance(d, Division) for d in divisions):
            raise ValueError(
                f"SoftLink.divisions = {divisions!r}: give one or more Division "
                "objects."
            )
        if not isinstance(material, Material):
            raise ValueError(f"SoftLink.material = {material!r}: give a Material.")
        self.joint = Joint("N") if joint is None else joint
        self.material = material
        self.divisions = divisions
        self.g_i = _pose("SoftLink.g_i", g_i)
        self.g_f = _pose("SoftLink.g_f", g_f)
        self.color = color

    @property
    def n_dof(self) -> int:
        """Joint coordinates plus all divisions' strain coordinates."""
        return self.joint.n_dof + sum(d.n_dof for d in self.divisions)

    @property
    def length(self) -> Array:
        """Total rod length [m]."""
        return sum(d.length for d in self.divisions)  # type: ignore[return-value]


class RigidLink(AbstractLink):
    """A rigid body behind a lumped joint.

    The body is a prism of ``length`` along local x and cross-section ``section``
    (used for the inertia when ``mass`` is not given, and for plots). By default the
    CM is at the middle: ``g_i`` = translation (L/2, 0, 0) from the joint and
    ``g_f`` = translation (L/2, 0, 0) from the CM to the tip.

    Attributes:
        joint: the lumped joint at the base.
        length: body length along x [m].
        section: cross-section of the prism.
        rho: density [kg/m^3] (used when ``mass`` is None).
        mass: mass [kg], or None to compute it from shape and density.
        inertia: 3x3 rotational inertia about the CM in the CM frame [kg m^2], or
            None to compute it from the shape.
        g_i: joint -> CM pose, or None for the centred default.
        g_f: CM -> tip pose, or None for the centred default.
        color: plot colour.
    """

    joint: Joint
    length: Float[Array, ""]
    section: AbstractSection
    rho: Float[Array, ""]
    mass: Float[Array, ""] | None
    inertia: Float[Array, "3 3"] | None
    g_i_: Float[Array, "4 4"] | None
    g_f_: Float[Array, "4 4"] | None
    color: str = eqx.field(static=True)

    def __init__(
        self,
        joint: Joint | None = None,
        length: ArrayLike = 0.1,
        section: AbstractSection | None = None,
        rho: ArrayLike = 1000.0,
        mass: ArrayLike | None = None,
        inertia: ArrayLike | None = None,
        g_i: ArrayLike | None = None,
        g_f: ArrayLike | None = None,
        color: str = "tab:gray",
    ):
        check_positive("RigidLink.length", length)
        check_positive("RigidLink.rho", rho, allow_zero=True)
        if mass is not None:
            check_positive("RigidLink.mass", mass, allow_zero=True)
        if inertia is not None:
            check_shape("RigidLink.inertia", inertia, (3, 3))
            _check_inertia(inertia)
        if section is None:
            section = CircularSection(0.01)
        self.joint = Joint("N") if joint is None else joint
        self.length = jnp.asarray(length, dtype=float)
        self.section = section
        self.rho = jnp.asarray(rho, dtype=float)
        self.mass = None if mass is None else jnp.asarray(mass, dtype=float)
        self.inertia = None if inertia is None else jnp.asarray(inertia, dtype=float)
        self.g_i_ = None if g_i is None else _pose("RigidLink.g_i", g_i)
        self.g_f_ = None if g_f is None else _pose("RigidLink.g_f", g_f)
        self.color = color

    @property
    def n_dof(self) -> int:
        """Joint coordinates (a rigid body adds none)."""
        return self.joint.n_dof

    @property
    def g_i(self) -> Array:
        """Joint -> CM pose."""
        return translation(self.length / 2) if self.g_i_ is None else self.g_i_

    @property
    def g_f(self) -> Array:  # pyright: ignore[reportIncompatibleVariableOverride]
        """CM -> tip pose."""
        return translation(self.length / 2) if self.g_f_ is None else self.g_f_

    def spatial_inertia(self) -> Float[Array, "6 6"]:
        """6x6 inertia at the CM, angular first: [[I, 0], [0, m 1]].

        From the prism (uniform density, section taken at its middle) unless ``mass``
        / ``inertia`` were given: Ixx = rho L Ip (Ip the polar moment),
        Iyy = rho L Iy + m L^2 / 12, Izz = rho L Iz + m L^2 / 12.
        """
        A, Iy, Iz, Ip = self.section.properties(0.5)
        L = self.length
        m_shape = self.rho * A * L
        m = m_shape if self.mass is None else self.mass
        if self.inertia is None:
            # Scale the shape's inertia to the given mass if only the mass was given.
            s = self.rho if self.mass is None else m / (A * L)
            I3 = s * jnp.diag(
                jnp.stack([Ip * L, Iy * L + A * L**3 / 12, Iz * L + A * L**3 / 12])
            )
        else:
            I3 = self.inertia
        M = jnp.zeros((6, 6), dtype=I3.dtype)
        M = M.at[:3, :3].set(I3)
        return M.at[3:, 3:].set(m * jnp.eye(3))


def _check_inertia(inertia) -> None:
    """Refuse a concrete rotational inertia that is not symmetric positive definite."""
    if not is_concrete(inertia):
        return
    I3 = np.asarray(inertia, dtype=float)
    check_finite("RigidLink.inertia", I3)
    scale = float(np.abs(I3).max())
    if not np.allclose(I3, I3.T, rtol=1e-9, atol=1e-12 * scale):
        raise ValueError(
            f"RigidLink.inertia = {I3.tolist()} is not symmetric: give the 3x3 "
            "rotational inertia at the centre of mass [kg m^2]."
        )
    eig = np.linalg.eigvalsh(I3)
    if eig[0] < -1e-12 * scale:
        raise ValueError(
            f"RigidLink.inertia = {I3.tolist()} has a negative eigenvalue "
            f"{eig[0]:.6g}: give a positive semi-definite 3x3 inertia at the centre "
            "of mass [kg m^2] (or leave it None for the prism's)."
        )
