"""Cross-sections of soft and rigid prismatic links.

Circle, rectangle and ellipse from their dimensions (profiles of X1: tapering), or
:class:`SectionProperties` given directly (measured, or from a finite-element section
solver). Conventions (DESIGN.md section 1): the rod axis is local x; ``Iy`` is the
second moment for bending about y, ``Iz`` about z.

Section mechanics. The stiffness of a section is
``Sigma = diag(G J, E Iy, E Iz, E A, G k_y A, G k_z A)``: ``J`` is the torsion
constant and ``k_y``, ``k_z`` the shear coefficients. By default (``torsion =
"saint-venant"``, ``shear_coefficient = None``) sorojax uses solid mechanics:

- ``J`` the Saint-Venant torsion constant: pi r^4 / 2 for a circle (its polar
  moment), pi a^3 b^3 / (a^2 + b^2) for an ellipse, and for a rectangle of sides
  ``b <= a`` the series ``a b^3 / 3 [1 - 192 b / (pi^5 a) sum_{n odd}
  tanh(n pi a / (2 b)) / n^5]`` (summed to n = 199: relative truncation error below
  1e-10), 0.1406 a^4 for a square;
- Cowper's shear coefficients (Cowper 1966, J. Appl. Mech. 33, 335): circle
  ``6 (1 + nu) / (7 + 6 nu)``, rectangle ``10 (1 + nu) / (12 + 11 nu)``, ellipse
  ``12 (1 + nu) m^2 (3 m^2 + 1) / ((40 + 37 nu) m^4 + (16 + 10 nu) m^2 + nu)`` with
  ``m`` the ratio of the semi-axis along the shear to the other one.

SoRoSim's model (polar moment ``J = Iy + Iz`` for torsion, no shear correction) is
``torsion="polar", shear_coefficient=1.0``; :func:`sorosim_mechanics` switches every
section of a linkage, link or division to it. The model is data (array leaves), not
structure: models that differ only in it share compiled programs (and can be
stacked for ``vmap``). Inertia always uses the polar moment
``Iy + Iz`` (rotary inertia about the axis); damping ``Upsilon`` uses the same ``J``
and ``k A`` as the stiffness.
"""

import abc
import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from ._checks import is_concrete
from ._profile import AbstractProfile, as_profile

TORSION_MODELS = ("saint-venant", "polar")
# Odd n = 1, 3, ..., 199 of the rectangle's torsion series.
_N_ODD = np.arange(1, 200, 2, dtype=float)


def _check_mechanics(name: str, torsion: str, shear_coefficient) -> float | None:
    if torsion not in TORSION_MODELS:
        raise ValueError(
            f"{name}.torsion = {torsion!r}: give 'saint-venant' (solid mechanics, "
            "default) or 'polar' (J = Iy + Iz, SoRoSim's model)."
        )
    if shear_coefficient is None:
        return None
    try:
        k = float(shear_coefficient)
    except (TypeError, ValueError):
        raise ValueError(
            f"{name}.shear_coefficient = {shear_coefficient!r}: give a number in "
            "(0, 1.5] (1: no shear correction, SoRoSim's model) or None (Cowper's)."
        ) from None
    if not (0.0 < k <= 1.5):
        raise ValueError(
            f"{name}.shear_coefficient = {shear_coefficient!r} is outside (0, 1.5]: "
            "give a shear coefficient in (0, 1.5] (1: no shear correction, SoRoSim's "
            "model) or None (Cowper's for this section)."
        )
    return k


def _mechanics_arrays(name: str, torsion: str, shear_coefficient):
    """``(polar, given, k)``: the section model as array leaves (module docstring)."""
    k = _check_mechanics(name, torsion, shear_coefficient)
    return (
        jnp.asarray(1.0 if torsion == "polar" else 0.0, dtype=float),
        jnp.asarray(0.0 if k is None else 1.0, dtype=float),
        jnp.asarray(1.0 if k is None else k, dtype=float),
    )


class AbstractSection(eqx.Module):
    """A cross-section whose area, moments and stiffness constants depend on X1."""

    @abc.abstractmethod
    def properties(self, X1) -> tuple[Array, Array, Array, Array]:
        """Return ``(A, Iy, Iz, Ip)`` at ``X1`` [m^2, m^4, m^4, m^4].

        ``Ip`` is the polar moment of area (``Iy + Iz`` for the built-in shapes), the
        rotary inertia density about the axis per unit density.
        """

    @abc.abstractmethod
    def stiffness_constants(self, X1, poisson) -> tuple[Array, Array, Array]:
        """Return ``(J, A_y, A_z)`` at ``X1`` for a Poisson ratio.

        ``J`` is the torsion constant, ``A_y = k_y A`` and ``A_z = k_z A`` the shear
        areas (A, Iy, Iz come from :meth:`properties`).
        """

    @abc.abstractmethod
    def extent(self, X1) -> tuple[Array, Array]:
        """Return the half-widths ``(along y, along z)`` at ``X1`` [m] (for plots)."""


class _ShapedSection(AbstractSection):
    """A section from its dimensions, with a torsion model and a shear coefficient.

    The model is held as array leaves (``polar``: 1 for ``J = Iy + Iz``, 0 for
    Saint-Venant; ``given``: 1 when ``shear_coefficient`` is given, 0 for Cowper's;
    ``k``: the given coefficient), so that switching it (e.g. with
    :func:`sorosim_mechanics`) keeps the model's structure and reuses compiled
    programs; ``torsion`` and ``shear_coefficient`` read them back.
    """

    polar: eqx.AbstractVar[Array]
    given: eqx.AbstractVar[Array]
    k: eqx.AbstractVar[Array]

    @property
    def torsion(self) -> str:
        """``"polar"`` or ``"saint-venant"`` (on a concrete section)."""
        return "polar" if float(self.polar) > 0.5 else "saint-venant"

    @property
    def shear_coefficient(self) -> float | None:
        """The given shear coefficient, or ``None`` for Cowper's (concrete section)."""
        return float(self.k) if float(self.given) > 0.5 else None

    def with_mechanics(self, torsion: str, shear_coefficient=None):
        """This section with another torsion model and shear coefficient."""
        arrays = _mechanics_arrays(type(self).__name__, torsion, shear_coefficient)
        return eqx.tree_at(lambda x: (x.polar, x.given, x.k), self, arrays)

    @abc.abstractmethod
    def _saint_venant(self, X1) -> Array:
        """Saint-Venant torsion constant at X1."""

    @abc.abstractmethod
    def _cowper(self, X1, poisson) -> tuple[Array, Array]:
        """Cowper's shear coefficients ``(k_y, k_z)``."""

    def torsion_constant(self, X1) -> Array:
        """Torsion constant ``J`` at ``X1`` [m^4] under this section's model."""
        _, Iy, Iz, _ = self.properties(X1)
        return jnp.where(self.polar > 0.5, Iy + Iz, self._saint_venant(X1))

    def shear_coefficients(self, X1, poisson) -> tuple[Array, Array]:
        """Shear coefficients ``(k_y, k_z)`` (given, or Cowper's for ``poisson``)."""
        ky, kz = self._cowper(X1, poisson)
        use = self.given > 0.5
        return jnp.where(use, self.k, ky), jnp.where(use, self.k, kz)

    def stiffness_constants(self, X1, poisson):
        """``(J, k_y A, k_z A)`` under this section's model."""
        A = self.properties(X1)[0]
        ky, kz = self.shear_coefficients(X1, poisson)
        return self.torsion_constant(X1), ky * A, kz * A


class CircularSection(_ShapedSection):
    """Solid circle of radius ``r(X1)``.

    Attributes:
        radius: profile of the radius [m].
        torsion: ``"saint-venant"`` or ``"polar"`` (the same for a circle).
        shear_coefficient: ``None`` for Cowper's ``6 (1 + nu) / (7 + 6 nu)``, or a
            number in (0, 1.5] (1: SoRoSim's model).
    """

    radius: AbstractProfile
    polar: Array
    given: Array
    k: Array

    def __init__(self, radius, *, torsion="saint-venant", shear_coefficient=None):
        self.radius = as_profile("CircularSection.radius", radius)
        self.polar, self.given, self.k = _mechanics_arrays(
            "CircularSection", torsion, shear_coefficient
        )

    def properties(self, X1):
        """``(A, Iy, Iz, Ip)`` of a circle: pi r^2, pi r^4 / 4 (twice), pi r^4 / 2."""
        r = self.radius(X1)
        I_ = math.pi * r**4 / 4
        return math.pi * r**2, I_, I_, 2 * I_

    def _saint_venant(self, X1):
        return math.pi * self.radius(X1) ** 4 / 2

    def _cowper(self, X1, poisson):
        k = 6 * (1 + poisson) / (7 + 6 * poisson)
        return k, k

    def extent(self, X1):
        """Radius along y and z."""
        r = self.radius(X1)
        return r, r


def rectangle_torsion_constant(h, w) -> Array:
    """Saint-Venant torsion constant of a solid ``h x w`` rectangle [m^4].

    ``a b^3 / 3 [1 - 192 b / (pi^5 a) sum_{n odd} tanh(n pi a / (2 b)) / n^5]`` with
    ``a = max(h, w)``, ``b = min(h, w)``, summed to n = 199 (truncation below 1e-10
    relative); square: 0.14058 a^4.

    With concrete (not traced) ``h`` and ``w`` the series is summed with NumPy: run
    eagerly with ``jax.numpy`` its dozen operations compile one XLA program each
    (~0.35 s on a first call).
    """
    traced = any(isinstance(x, jax.core.Tracer) for x in (h, w))
    xp = jnp if traced else np
    a, b = xp.maximum(h, w), xp.minimum(h, w)
    s = xp.sum(
        xp.tanh(xp.expand_dims(xp.pi * a / (2 * b), -1) * _N_ODD) / _N_ODD**5, -1
    )
    J = a * b**3 / 3 * (1 - 192 / xp.pi**5 * (b / a) * s)
    return J if traced else jnp.asarray(J, jnp.result_type(h, w, float))


class RectangularSection(_ShapedSection):
    """Solid rectangle, ``width`` along local y and ``height`` along local z.

    Attributes:
        height: profile of the height along z [m].
        width: profile of the width along y [m].
        torsion: ``"saint-venant"`` (series, default) or ``"polar"`` (Iy + Iz).
        shear_coefficient: ``None`` for Cowper's ``10 (1 + nu) / (12 + 11 nu)``, or
            a number in (0, 1.5] (1: SoRoSim's model).
    """

    height: AbstractProfile
    width: AbstractProfile
    polar: Array
    given: Array
    k: Array

    def __init__(
        self, height, width, *, torsion="saint-venant", shear_coefficient=None
    ):
        self.height = as_profile("RectangularSection.height", height)
        self.width = as_profile("RectangularSection.width", width)
        self.polar, self.given, self.k = _mechanics_arrays(
            "RectangularSection", torsion, shear_coefficient
        )

    def properties(self, X1):
        """``(A, Iy, Iz, Ip)``: w h, w h^3 / 12, h w^3 / 12, Iy + Iz."""
        h, w = self.height(X1), self.width(X1)
        Iy = w * h**3 / 12
        Iz = h * w**3 / 12
        return w * h, Iy, Iz, Iy + Iz

    def _saint_venant(self, X1):
        return rectangle_torsion_constant(self.height(X1), self.width(X1))

    def _cowper(self, X1, poisson):
        k = 10 * (1 + poisson) / (12 + 11 * poisson)
        return k, k

    def extent(self, X1):
        """Half width along y, half height along z."""
        return self.width(X1) / 2, self.height(X1) / 2


def _cowper_ellipse(m, nu):
    """Cowper's coefficient of an ellipse, ``m`` = semi-axis along the shear / other."""
    m2 = m * m
    return (
        12
        * (1 + nu)
        * m2
        * (3 * m2 + 1)
        / ((40 + 37 * nu) * m2 * m2 + (16 + 10 * nu) * m2 + nu)
    )


class EllipticalSection(_ShapedSection):
    """Solid ellipse, semi-axis ``a`` along local y and ``b`` along local z.

    Attributes:
        a: profile of the semi-axis along y [m].
        b: profile of the semi-axis along z [m].
        torsion: ``"saint-venant"`` (pi a^3 b^3 / (a^2 + b^2), default) or
            ``"polar"`` (Iy + Iz).
        shear_coefficient: ``None`` for Cowper's (per direction, see the module), or
            a number in (0, 1.5] (1: SoRoSim's model).
    """

    a: AbstractProfile
    b: AbstractProfile
    polar: Array
    given: Array
    k: Array

    def __init__(self, a, b, *, torsion="saint-venant", shear_coefficient=None):
        self.a = as_profile("EllipticalSection.a", a)
        self.b = as_profile("EllipticalSection.b", b)
        self.polar, self.given, self.k = _mechanics_arrays(
            "EllipticalSection", torsion, shear_coefficient
        )

    def properties(self, X1):
        """``(A, Iy, Iz, Ip)``: pi a b, pi a b^3 / 4, pi a^3 b / 4, Iy + Iz."""
        a, b = self.a(X1), self.b(X1)
        Iy = math.pi * a * b**3 / 4
        Iz = math.pi * a**3 * b / 4
        return math.pi * a * b, Iy, Iz, Iy + Iz

    def _saint_venant(self, X1):
        a, b = self.a(X1), self.b(X1)
        return math.pi * a**3 * b**3 / (a**2 + b**2)

    def _cowper(self, X1, poisson):
        a, b = self.a(X1), self.b(X1)
        return _cowper_ellipse(a / b, poisson), _cowper_ellipse(b / a, poisson)

    def extent(self, X1):
        """Semi-axes along y and z."""
        return self.a(X1), self.b(X1)


class AnnularSection(_ShapedSection):
    """Hollow circle (a tube wall) between radii ``inner(X1) < outer(X1)``.

    Attributes:
        outer: profile of the outer radius [m].
        inner: profile of the inner radius [m] (0 < inner < outer).
        torsion: ``"saint-venant"`` or ``"polar"`` (the same for a circular tube:
            J = pi (R^4 - r^4) / 2).
        shear_coefficient: ``None`` for Cowper's hollow-circle coefficient
            ``6 (1 + nu) (1 + m^2)^2 / ((7 + 6 nu) (1 + m^2)^2 + (20 + 12 nu) m^2)``,
            m = r / R (Cowper 1966), or a number in (0, 1.5].
    """

    outer: AbstractProfile
    inner: AbstractProfile
    polar: Array
    given: Array
    k: Array

    def __init__(self, outer, inner, *, torsion="saint-venant", shear_coefficient=None):
        self.outer = as_profile("AnnularSection.outer", outer)
        self.inner = as_profile("AnnularSection.inner", inner)
        for x in (0.0, 0.5, 1.0):
            R, r = self.outer(x), self.inner(x)
            if is_concrete(R) and is_concrete(r) and not float(r) < float(R):
                raise ValueError(
                    f"AnnularSection.inner = {float(r)!r} at X1 = {x} is not below "
                    f"outer = {float(R)!r}: give 0 < inner < outer [m]."
                )
        self.polar, self.given, self.k = _mechanics_arrays(
            "AnnularSection", torsion, shear_coefficient
        )

    def properties(self, X1):
        """``(A, Iy, Iz, Ip)`` of a tube: pi (R^2 - r^2), pi (R^4 - r^4) / 4, ..."""
        R, r = self.outer(X1), self.inner(X1)
        I_ = math.pi * (R**4 - r**4) / 4
        return math.pi * (R**2 - r**2), I_, I_, 2 * I_

    def _saint_venant(self, X1):
        R, r = self.outer(X1), self.inner(X1)
        return math.pi * (R**4 - r**4) / 2

    def _cowper(self, X1, poisson):
        m2 = (self.inner(X1) / self.outer(X1)) ** 2
        a = (1 + m2) ** 2
        k = 6 * (1 + poisson) * a / ((7 + 6 * poisson) * a + (20 + 12 * poisson) * m2)
        return k, k

    def extent(self, X1):
        """Outer radius along y and z."""
        R = self.outer(X1)
        return R, R

    def inner_radius(self, X1):
        """The bore's radius at ``X1`` [m] (contact on the inner surface)."""
        return self.inner(X1)


class SectionProperties(AbstractSection):
    """A section given by its properties (measured, or from a FE section solver).

    Each value is a number or a profile of X1. Used as given: no model switch applies.

    Attributes:
        A: area [m^2], > 0.
        Iy: second moment for bending about y [m^4], > 0.
        Iz: second moment for bending about z [m^4], > 0.
        J: torsion constant [m^4], > 0.
        shear_area_y: effective shear area along y, ``k_y A`` [m^2], > 0; default A.
        shear_area_z: effective shear area along z, ``k_z A`` [m^2], > 0; default A.
        polar_moment: polar moment of area for the rotary inertia [m^4]; default
            Iy + Iz.
    """

    A: AbstractProfile
    Iy: AbstractProfile
    Iz: AbstractProfile
    J: AbstractProfile
    shear_area_y: AbstractProfile | None
    shear_area_z: AbstractProfile | None
    polar_moment: AbstractProfile | None

    def __init__(
        self, A, Iy, Iz, J, shear_area_y=None, shear_area_z=None, polar_moment=None
    ):
        def prof(field, v):
            return None if v is None else as_profile(f"SectionProperties.{field}", v)

        self.A = prof("A", A)
        self.Iy = prof("Iy", Iy)
        self.Iz = prof("Iz", Iz)
        self.J = prof("J", J)
        self.shear_area_y = prof("shear_area_y", shear_area_y)
        self.shear_area_z = prof("shear_area_z", shear_area_z)
        self.polar_moment = prof("polar_moment", polar_moment)

    def properties(self, X1):
        """``(A, Iy, Iz, Ip)`` as given (``Ip`` default ``Iy + Iz``)."""
        Iy, Iz = self.Iy(X1), self.Iz(X1)
        Ip = Iy + Iz if self.polar_moment is None else self.polar_moment(X1)
        return self.A(X1), Iy, Iz, Ip

    def stiffness_constants(self, X1, poisson):
        """``(J, A_y, A_z)`` as given (shear areas default A)."""
        A = self.A(X1)
        Ay = A if self.shear_area_y is None else self.shear_area_y(X1)
        Az = A if self.shear_area_z is None else self.shear_area_z(X1)
        return self.J(X1), Ay, Az

    def extent(self, X1):
        """Half-widths of the rectangle with the same A, Iy, Iz (for plots)."""
        A = self.A(X1)
        return jnp.sqrt(3 * self.Iz(X1) / A), jnp.sqrt(3 * self.Iy(X1) / A)


def sorosim_mechanics(tree):
    """``tree`` (a section, division, link or linkage) with SoRoSim's section model.

    Every circle, rectangle and ellipse in it gets ``torsion="polar"`` (J = Iy + Iz)
    and ``shear_coefficient=1`` (no shear correction), which reproduces SoRoSim's
    stiffness and damping exactly. :class:`SectionProperties` are kept as given.
    """

    def switch(x):
        if isinstance(x, _ShapedSection):
            return x.with_mechanics("polar", 1.0)
        return x

    return jax.tree_util.tree_map(
        switch, tree, is_leaf=lambda x: isinstance(x, _ShapedSection)
    )


def section_matrices(
    section: AbstractSection, X1, E, G, rho, eta, poisson
) -> tuple[Float[Array, "6 6"], Float[Array, "6 6"], Float[Array, "6 6"]]:
    """Stiffness, inertia density and damping of a section at ``X1`` (DESIGN.md 1).

    Returns:
        ``(Sigma, M_s, Upsilon)``: diag(G J, E Iy, E Iz, E A, G A_y, G A_z),
        rho diag(Ip, Iy, Iz, A, A, A) and eta diag(J, 3 Iy, 3 Iz, 3 A, A_y, A_z),
        with ``J`` the torsion constant, ``A_y = k_y A``, ``A_z = k_z A`` the shear
        areas and ``Ip`` the polar moment (module docstring).
    """
    A, Iy, Iz, Ip = section.properties(X1)
    J, Ay, Az = section.stiffness_constants(X1, poisson)
    Sigma = jnp.diag(jnp.stack([G * J, E * Iy, E * Iz, E * A, G * Ay, G * Az]))
    M_s = rho * jnp.diag(jnp.stack([Ip, Iy, Iz, A, A, A]))
    Upsilon = eta * jnp.diag(jnp.stack([J, 3 * Iy, 3 * Iz, 3 * A, Ay, Az]))
    return Sigma, M_s, Upsilon
