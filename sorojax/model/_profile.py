"""Profiles: a section dimension as a function of the normalised X1 in [0, 1].

A dimension may be a constant, a linear taper, or any pure JAX function of X1. The
first two keep their values as arrays, so ``jax.grad`` reaches them.
"""

import abc
from collections.abc import Callable

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Float

from ._checks import check_positive


class AbstractProfile(eqx.Module):
    """A positive scalar function of X1 in [0, 1]."""

    @abc.abstractmethod
    def __call__(self, X1: Float[ArrayLike, ""]) -> Float[Array, ""]:
        """Value at the normalised coordinate ``X1``."""


class Constant(AbstractProfile):
    """Constant value.

    Attributes:
        value: the value (e.g. a radius in m).
    """

    value: Float[Array, ""]

    def __call__(self, X1):
        """Value at ``X1`` (independent of it)."""
        return self.value + 0.0 * jnp.asarray(X1, dtype=self.value.dtype)


class Linear(AbstractProfile):
    """Linear taper from ``start`` at X1 = 0 to ``end`` at X1 = 1.

    Attributes:
        start: value at X1 = 0.
        end: value at X1 = 1.
    """

    start: Float[Array, ""]
    end: Float[Array, ""]

    def __call__(self, X1):
        """Value at ``X1``."""
        return self.start + (self.end - self.start) * X1


class Custom(AbstractProfile):
    """A user function of X1 (pure JAX; returns a scalar).

    Attributes:
        fn: the function ``X1 -> value``.
    """

    fn: Callable = eqx.field(static=True)

    def __call__(self, X1):
        """Value at ``X1``."""
        return jnp.asarray(self.fn(X1))


def as_profile(field: str, value) -> AbstractProfile:
    """Turn a number, a ``(start, end)`` pair or a function of X1 into a profile.

    Raises:
        ValueError: a constant or an end value that is not positive.
    """
    if isinstance(value, AbstractProfile):
        return value
    if callable(value):
        return Custom(value)
    if isinstance(value, tuple | list):
        if len(value) != 2:
            raise ValueError(
                f"{field} = {value!r}: a taper is given as (start, end), two values."
            )
        check_positive(f"{field}[0]", value[0])
        check_positive(f"{field}[1]", value[1])
        return Linear(jnp.asarray(value[0], float), jnp.asarray(value[1], float))
    check_positive(field, value)
    return Constant(jnp.asarray(value, dtype=float))
