"""A linkage's hook (a user function) with its array parameters as model arrays.

A linkage's hooks (``custom_wrench``, ``custom_actuation``, ``actuator_strength``) are
user functions. A plain function is part of the model's static structure: the
compiled programs are keyed by the function object. A hook may also carry its
parameters as arrays, as an ``equinox.Partial(f, *args)`` of a module-level ``f`` or
as an ``equinox.Module`` with a ``__call__``: its array leaves (JAX or NumPy arrays)
then become arrays of the model, as E or a radius are. A new value (a new target or
gain of a controller) reuses the compiled programs, ``jax.grad`` reaches it, and
``vmap`` over stacked models batches it. Everything else in the hook (the function,
Python numbers, strings) stays static: a change recompiles. A closure's captured
values are constants of the compiled program, whatever their type.
"""

from collections.abc import Callable
from typing import Any

import equinox as eqx
import jax


class Hook(eqx.Module):
    """A hook function split into its array leaves and its static rest.

    Calling it calls the user's function with the arrays put back (traced inside a
    compiled program). Built by :class:`~sorojax.Linkage` from the function given;
    :attr:`function` gives that function back.
    """

    arrays: Any
    treedef: Any = eqx.field(static=True)
    leaves: tuple = eqx.field(static=True)

    def __init__(self, fn: Callable, name: str = "hook"):
        if not callable(fn):
            raise ValueError(f"Linkage.{name} = {fn!r}: give a function or None.")
        arrays, static = eqx.partition(fn, eqx.is_array)
        leaves, treedef = jax.tree_util.tree_flatten(static)
        leaves = tuple(leaves)
        try:
            hash(leaves)
        except TypeError as e:
            raise ValueError(
                f"Linkage.{name} = {fn!r} holds an unhashable non-array value ({e}); "
                "give its parameters as arrays (jnp.asarray) or hashable Python "
                "values (numbers, strings, tuples), e.g. equinox.Partial(f, "
                "jnp.asarray(target))."
            ) from None
        self.arrays = arrays
        self.treedef = treedef
        self.leaves = leaves

    @property
    def function(self) -> Callable:
        """The user's function, with this hook's (possibly traced) arrays."""
        static = jax.tree_util.tree_unflatten(self.treedef, self.leaves)
        return eqx.combine(self.arrays, static)

    def __call__(self, *args):
        return self.function(*args)


def as_hook(fn: Callable | Hook | None, name: str) -> Hook | None:
    """``fn`` as a :class:`Hook` (None stays None; a Hook is kept)."""
    if fn is None or isinstance(fn, Hook):
        return fn
    return Hook(fn, name)
