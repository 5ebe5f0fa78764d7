"""Cross-sections of soft and rigid prismatic links: circle, rectangle, ellipse.

Dimensions are profiles of X1 (tapering). Conventions (DESIGN.md section 1): the rod
axis is local x; ``Iy`` is the second moment for bending about y, ``Iz`` about z, and
the polar moment is ``J = Iy + Iz``.
"""

import abc
import math

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Float

from ._profile import AbstractProfile, as_profile


class AbstractSection(eqx.Module):
    """A cross-section whose area and moments are functions of X1."""

    @abc.abstractmethod
    def properties(self, X1) -> tuple[Array, Array, Array, Array]:
        """Return ``(A, Iy, Iz, J)`` at ``X1`` [m^2, m^4, m^4, m^4]."""

    @abc.abstractmethod
    def extent(self, X1) -> tuple[Array, Array]:
        """Return the half-widths ``(along y, along z)`` at ``X1`` [m] (for plots)."""


class CircularSection(AbstractSection):
    """Solid circle of radius ``r(X1)``.

    Attributes:
        radius: profile of the radius [m].
    """

    radius: AbstractProfile

    def __init__(self, radius):
        self.radius = as_profile("CircularSection.radius", radius)

    def properties(self, X1):
        """``(A, Iy, Iz, J)`` of a circle: pi r^2, pi r^4 / 4 (twice), pi r^4 / 2."""
        r = self.radius(X1)
        I_ = math.pi * r**4 / 4
        return math.pi * r**2, I_, I_, 2 * I_

    def extent(self, X1):
        """Radius along y and z."""
        r = self.radius(X1)
        return r, r


class RectangularSection(AbstractSection):
    """Solid rectangle, ``width`` along local y and ``height`` along local z.

    Attributes:
        height: profile of the height along z [m].
        width: profile of the width along y [m].
    """

    height: AbstractProfile
    width: AbstractProfile

    def __init__(self, height, width):
        self.height = as_profile("RectangularSection.height", height)
        self.width = as_profile("RectangularSection.width", width)

    def properties(self, X1):
        """``(A, Iy, Iz, J)``: w h, w h^3 / 12, h w^3 / 12, Iy + Iz."""
        h, w = self.height(X1), self.width(X1)
        Iy = w * h**3 / 12
        Iz = h * w**3 / 12
        return w * h, Iy, Iz, Iy + Iz

    def extent(self, X1):
        """Half width along y, half height along z."""
        return self.width(X1) / 2, self.height(X1) / 2


class EllipticalSection(AbstractSection):
    """Solid ellipse, semi-axis ``a`` along local y and ``b`` along local z.

    Attributes:
        a: profile of the semi-axis along y [m].
        b: profile of the semi-axis along z [m].
    """

    a: AbstractProfile
    b: AbstractProfile

    def __init__(self, a, b):
        self.a = as_profile("EllipticalSection.a", a)
        self.b = as_profile("EllipticalSection.b", b)

    def properties(self, X1):
        """``(A, Iy, Iz, J)``: pi a b, pi a b^3 / 4, pi a^3 b / 4, Iy + Iz."""
        a, b = self.a(X1), self.b(X1)
        Iy = math.pi * a * b**3 / 4
        Iz = math.pi * a**3 * b / 4
        return math.pi * a * b, Iy, Iz, Iy + Iz

    def extent(self, X1):
        """Semi-axes along y and z."""
        return self.a(X1), self.b(X1)


def section_matrices(
    section: AbstractSection, X1, E, G, rho, eta
) -> tuple[Float[Array, "6 6"], Float[Array, "6 6"], Float[Array, "6 6"]]:
    """Stiffness, inertia density and damping of a section at ``X1`` (DESIGN.md 1).

    Returns:
        ``(Sigma, M_s, Upsilon)``: diag(G J, E Iy, E Iz, E A, G A, G A),
        rho diag(J, Iy, Iz, A, A, A) and eta diag(J, 3 Iy, 3 Iz, 3 A, A, A).
    """
    A, Iy, Iz, J = section.properties(X1)
    Sigma = jnp.diag(jnp.stack([G * J, E * Iy, E * Iz, E * A, G * A, G * A]))
    M_s = rho * jnp.diag(jnp.stack([J, Iy, Iz, A, A, A]))
    Upsilon = eta * jnp.diag(jnp.stack([J, 3 * Iy, 3 * Iz, 3 * A, A, A]))
    return Sigma, M_s, Upsilon
