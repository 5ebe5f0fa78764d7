"""Strain bases of soft divisions: which modes are active and with what polynomials.

A division's strain is ``xi(X) = Phi(X) q + xi_ref(X)`` (DESIGN.md section 2). The basis
returns the *normalised* block matrix ``Phi_n(X1)`` of shape ``(6, n_dof)``: one block
per active mode, each row a polynomial family on X1 in [0, 1]. The linkage scales the
angular rows by 1 / (division length) so that the coordinates q are dimensionless.
Only active modes get coordinates: an inextensible, shearless rod has none for
elongation and shear.
"""

import abc
from collections.abc import Callable

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Float

MODE_NAMES = ("torsion", "bend_y", "bend_z", "elongation", "shear_y", "shear_z")


def _normalise(cls_name: str, modes, orders) -> tuple[tuple[int, ...], tuple[int, ...]]:
    try:
        bad = [m for m in modes if m not in (0, 1)]
        modes_t = tuple(int(bool(m)) for m in modes)
    except TypeError:
        raise ValueError(
            f"{cls_name}.modes = {modes!r}: give six 0/1 flags for {MODE_NAMES}."
        ) from None
    if bad:
        raise ValueError(
            f"{cls_name}.modes = {modes!r} holds {bad[0]!r}: give six 0/1 flags "
            f"(on/off, not orders: orders go in `orders`) for {MODE_NAMES}."
        )
    if len(modes_t) != 6:
        raise ValueError(
            f"{cls_name}.modes = {modes!r} has {len(modes_t)} entries: give six 0/1 "
            f"flags for {MODE_NAMES}."
        )
    if isinstance(orders, int):
        orders_t = tuple(orders if m else 0 for m in modes_t)
    else:
        orders_t = tuple(int(o) for o in orders)
        if len(orders_t) != 6:
            raise ValueError(
                f"{cls_name}.orders = {orders!r} has {len(orders_t)} entries: give one "
                "integer, or six (one per mode)."
            )
    for name, o in zip(MODE_NAMES, orders_t, strict=True):
        if o < 0:
            raise ValueError(
                f"{cls_name}.orders[{name}] = {o} is negative: polynomial orders are "
                "integers >= 0 (0 = constant strain)."
            )
    return modes_t, orders_t


class AbstractStrainBasis(eqx.Module):
    """Maps X1 in [0, 1] to the normalised basis matrix ``(6, n_dof)``."""

    @property
    @abc.abstractmethod
    def n_dof(self) -> int:
        """Number of coordinates of the division."""

    @property
    @abc.abstractmethod
    def max_order(self) -> int:
        """Highest polynomial order (sets the default number of Gauss points)."""

    @abc.abstractmethod
    def __call__(self, X1) -> Float[Array, "6 n_dof"]:
        """Normalised basis at ``X1`` (angular rows not yet divided by the length)."""

    @property
    def column_modes(self) -> tuple[tuple[int, ...], ...]:
        """For each column, the strain rows (0-5) where it may be nonzero.

        Every row unless a basis knows better (a polynomial basis: one row per
        column). Static: the kernels of many contact samples multiply by the
        nonzero entries only.
        """
        return ((0, 1, 2, 3, 4, 5),) * self.n_dof


class AbstractPolynomialBasis(AbstractStrainBasis):
    """Block basis: for each active mode, polynomials of orders 0..order on X1."""

    modes: eqx.AbstractVar[tuple[int, ...]]
    orders: eqx.AbstractVar[tuple[int, ...]]

    @abc.abstractmethod
    def polynomials(self, X1, order: int) -> Float[Array, " order+1"]:
        """Values of the family's polynomials 0..order at ``X1``."""

    @property
    def n_dof(self) -> int:
        """Sum over active modes of (order + 1)."""
        return sum(o + 1 for m, o in zip(self.modes, self.orders, strict=True) if m)

    @property
    def max_order(self) -> int:
        """Highest order over active modes (0 if none)."""
        return max(
            (o for m, o in zip(self.modes, self.orders, strict=True) if m), default=0
        )

    @property
    def column_modes(self) -> tuple[tuple[int, ...], ...]:
        """Each column's one strain row: its mode's."""
        return tuple(
            (row,)
            for row, (m, o) in enumerate(zip(self.modes, self.orders, strict=True))
            if m
            for _ in range(o + 1)
        )

    def __call__(self, X1):
        """Block-structured ``(6, n_dof)`` basis at ``X1``."""
        X1 = jnp.asarray(X1, dtype=float)
        cols = []
        for row, (m, o) in enumerate(zip(self.modes, self.orders, strict=True)):
            if not m:
                continue
            p = self.polynomials(X1, o)
            block = jnp.zeros((6, o + 1), dtype=X1.dtype).at[row].set(p)
            cols.append(block)
        if not cols:
            return jnp.zeros((6, 0), dtype=X1.dtype)
        return jnp.concatenate(cols, axis=1)


class LegendreBasis(AbstractPolynomialBasis):
    """Shifted Legendre polynomials P_k(2 X1 - 1) (orthogonal on [0, 1]; default).

    Attributes:
        modes: six 0/1 flags (torsion, bend y, bend z, elongation, shear y, shear z).
        orders: polynomial order per mode (an int applies to every active mode).
    """

    modes: tuple[int, ...] = eqx.field(static=True)
    orders: tuple[int, ...] = eqx.field(static=True)

    def __init__(self, modes=(1, 1, 1, 0, 0, 0), orders=0):
        self.modes, self.orders = _normalise("LegendreBasis", modes, orders)

    def polynomials(self, X1, order):
        """P_0..P_order at 2 X1 - 1 by Bonnet's recursion."""
        x = 2.0 * X1 - 1.0
        ps = [jnp.ones_like(x)]
        if order >= 1:
            ps.append(x)
        for k in range(1, order):
            ps.append(((2 * k + 1) * x * ps[k] - k * ps[k - 1]) / (k + 1))
        return jnp.stack(ps)


class MonomialBasis(AbstractPolynomialBasis):
    """Monomials 1, X1, X1^2, ... (as in the SoRoSim manual's tables).

    Attributes:
        modes: six 0/1 flags (torsion, bend y, bend z, elongation, shear y, shear z).
        orders: polynomial order per mode (an int applies to every active mode).
    """

    modes: tuple[int, ...] = eqx.field(static=True)
    orders: tuple[int, ...] = eqx.field(static=True)

    def __init__(self, modes=(1, 1, 1, 0, 0, 0), orders=0):
        self.modes, self.orders = _normalise("MonomialBasis", modes, orders)

    def polynomials(self, X1, order):
        """1, X1, ..., X1^order."""
        return jnp.stack([X1**k for k in range(order + 1)])


class CustomBasis(AbstractStrainBasis):
    """A user basis: a pure JAX function ``X1 -> (6, n_dof)`` array.

    Attributes:
        fn: the basis function.
        dofs: number of columns it returns.
        order: polynomial degree to size the default quadrature (a guess is fine).
    """

    fn: Callable = eqx.field(static=True)
    dofs: int = eqx.field(static=True)
    order: int = eqx.field(static=True, default=3)

    def __check_init__(self):
        if self.dofs < 0:
            raise ValueError(f"CustomBasis.dofs = {self.dofs} is negative: give >= 0.")

    @property
    def n_dof(self) -> int:
        """Number of columns of the user basis."""
        return self.dofs

    @property
    def max_order(self) -> int:
        """The declared polynomial degree."""
        return self.order

    def __call__(self, X1):
        """User basis at ``X1``, checked for shape ``(6, n_dof)``."""
        out = jnp.asarray(self.fn(jnp.asarray(X1, dtype=float)))
        if out.shape != (6, self.dofs):
            raise ValueError(
                f"CustomBasis.fn returned shape {out.shape}; expected (6, {self.dofs})."
            )
        return out


class PaddedBasis(AbstractStrainBasis):
    """A polynomial basis padded to a size class (see :func:`~sorojax.size_class`).

    The class's basis has every padded mode at the class order; ``active`` keeps the
    model's own columns (1) and zeroes the padding (0). Because ``active`` is an
    array, models of one class share every compiled program whatever their own
    orders (and, with ``modes`` padded too, their own modes). The padded
    coordinates have zero basis columns: the linkage holds them at zero with a
    stiffness and an inertia of their own (:func:`~sorojax.model.precompute`).

    Attributes:
        basis: the class's basis.
        active: ``(n_dof,)`` 1.0 for the model's own columns, 0.0 for padding.
    """

    basis: AbstractPolynomialBasis
    active: Float[Array, " n_dof"]

    @property
    def n_dof(self) -> int:
        """Columns of the class's basis (the model's own and the padding)."""
        return self.basis.n_dof

    @property
    def max_order(self) -> int:
        """The class order (it sets the Magnus order and the default points)."""
        return self.basis.max_order

    @property
    def column_modes(self) -> tuple[tuple[int, ...], ...]:
        """The class's basis's (padded columns are zero on every row)."""
        return self.basis.column_modes

    def __call__(self, X1):
        """The class's basis with the padded columns zero."""
        return self.basis(X1) * self.active[None, :]
