"""Batched parameter sweeps sharded over every device JAX sees.

``sweep(fn, *args)`` is ``jax.vmap(fn)(*args)`` compiled once, with the batch split
evenly over ``jax.devices()`` (GPUs of a multi-GPU host; on a CPU, the host
devices that ``XLA_FLAGS=--xla_force_host_platform_device_count=N`` creates, one
per core: XLA runs each device's share on its own thread, where one vmapped
program runs its small kernels mostly on one core) and, with ``chunk``, run in
chunks of that many cases per device one after another (``lax.map`` over chunks:
bounded memory for very large sweeps on an accelerator). The batch is padded to a
whole number of chunks with copies of its last case and the padding is dropped
from the result.

What it does not do: change the solvers. A vmapped ``solve_statics`` runs its
Newton loop until the slowest case converges (converged cases idle in the loop),
and a vmapped ``simulate`` takes the adaptive steps of its fastest-varying case for
the whole batch; sort or group cases by difficulty when that matters.
"""

import functools
from collections.abc import Callable, Sequence

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh, NamedSharding, PartitionSpec

from ._jit import compiler_options


def _batch_size(args) -> int:
    sizes = {int(np.shape(x)[0]) for x in jax.tree.leaves(args) if np.ndim(x) > 0}
    if len(sizes) != 1:
        raise ValueError(
            f"sweep: the batched arguments' leading axes differ or are missing "
            f"({sorted(sizes)}); give every array leaf the same number of cases "
            "along axis 0 (close over the unbatched ones)."
        )
    return sizes.pop()


@functools.lru_cache(maxsize=32)
def _compiled(fn, n_dev, chunk, devices):
    mesh = Mesh(np.asarray(devices), ("cases",))
    shard = NamedSharding(mesh, PartitionSpec("cases"))
    batched = jax.vmap(fn)

    def run(args):
        if chunk is None:
            return batched(*args)
        # (n_dev * n_chunks * chunk, ...) -> (n_chunks, n_dev * chunk, ...): each
        # chunk keeps every device busy
        lead = jax.tree.leaves(args)[0].shape[0]
        n_chunks = lead // (n_dev * chunk)

        def split(x):
            x = x.reshape(n_dev, n_chunks, chunk, *x.shape[1:])
            return jnp.swapaxes(x, 0, 1).reshape(n_chunks, n_dev * chunk, *x.shape[3:])

        def merge(y):
            y = y.reshape(n_chunks, n_dev, chunk, *y.shape[2:])
            return jnp.swapaxes(y, 0, 1).reshape(n_chunks * n_dev * chunk, *y.shape[3:])

        out = jax.lax.map(lambda a: batched(*a), jax.tree.map(split, args))
        return jax.tree.map(merge, out)

    return jax.jit(
        run,
        in_shardings=(shard,),
        out_shardings=shard,
        compiler_options=compiler_options(),
    ), shard


def sweep(
    fn: Callable,
    *args,
    chunk: int | None = None,
    devices: Sequence[jax.Device] | None = None,
):
    """``jax.vmap(fn)(*args)``, compiled once and sharded over the devices.

    Args:
        fn: a pure function of one case's arguments (pytrees of arrays), e.g.
            ``lambda E: tip(solve_statics(with_E(lk, E), throw=False))``. Pass
            ``throw=False`` to sorojax solvers inside it and read their result
            codes: one failing case must not stop the sweep.
        *args: the cases: pytrees whose array leaves all have the same leading
            axis (the number of cases).
        chunk: cases per device per pass (None: all at once).
        devices: the devices to use (default ``jax.devices()``).

    Returns:
        ``fn``'s outputs stacked along a leading axis, one row per case (on the
        devices, sharded; ``np.asarray`` gathers them).

    Raises:
        ValueError: no cases, leading axes that differ, or ``chunk`` < 1.

    Example:
        On a CPU, set ``XLA_FLAGS=--xla_force_host_platform_device_count=2`` (one
        device per core) before JAX starts, then::

            tips = sorojax.sweep(tip_of_load, jnp.linspace(0.0, 10.0, 1024))
    """
    devices = tuple(jax.devices() if devices is None else devices)
    n = _batch_size(args)
    if n == 0:
        raise ValueError("sweep: no cases (the leading axis has length 0).")
    if chunk is not None and chunk < 1:
        raise ValueError(f"sweep: chunk = {chunk}; give a positive number of cases.")
    n_dev = len(devices)
    per_pass = n_dev * (chunk if chunk is not None else 1)
    if chunk is None:
        # the batch split evenly over the devices, the rest padded
        padded = -(-n // n_dev) * n_dev
    else:
        padded = -(-n // per_pass) * per_pass
    if padded != n:
        args = jax.tree.map(
            lambda x: jnp.concatenate(
                [x, jnp.repeat(x[-1:], padded - n, axis=0)], axis=0
            ),
            args,
        )
    run, shard = _compiled(fn, n_dev, chunk, devices)
    args = jax.device_put(args, shard)
    out = run(args)
    if padded != n:
        out = jax.tree.map(lambda y: y[:n], out)
    return out
