"""Batched parameter sweeps sharded over every device JAX sees.

``sweep(fn, *args)`` is ``jax.vmap(fn)(*args)`` compiled once, with the batch split
evenly over ``jax.devices()`` (GPUs of a multi-GPU host; on a CPU, the host
devices that ``XLA_FLAGS=--xla_force_host_platform_device_count=N`` creates, one
per core: XLA runs each device's share on its own thread, where one vmapped
program runs its small kernels mostly on one core). Each device runs its share as
an independent program (one asynchronous dispatch per device, compiled once per
device), so a solver loop ends per device, without collectives: a sharded ``jit``
of the same vmap kept the loops global and stalled on 2 CPU host devices at 1024
cases, and ``pmap`` / ``shard_map`` trip lineax's structure check inside the
statics solve (sharded abstract values) in JAX 0.10. With ``chunk``, each device
runs its cases in chunks of that many, one after another (``lax.map`` over chunks:
each chunk's loops end with its own slowest case, and memory stays bounded for very
large sweeps on an accelerator). The batch is padded to a
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
def _compiled(fn, chunk, devices):
    batched = jax.vmap(fn)

    def local(args):
        # One device's cases, its own loops: a Newton loop stops when *its* slowest
        # case converges, with no collective between devices.
        if chunk is None:
            return batched(*args)
        lead = jax.tree.leaves(args)[0].shape[0]

        def split(x):
            return x.reshape(lead // chunk, chunk, *x.shape[1:])

        def merge(y):
            return y.reshape(lead, *y.shape[2:])

        out = jax.lax.map(lambda a: batched(*a), jax.tree.map(split, args))
        return jax.tree.map(merge, out)

    return jax.jit(local, compiler_options=compiler_options())


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
        first device).

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
    per_pass = n_dev * (1 if chunk is None else chunk)
    padded = -(-n // per_pass) * per_pass  # whole passes of every device
    if padded != n:
        args = jax.tree.map(
            lambda x: jnp.concatenate(
                [x, jnp.repeat(x[-1:], padded - n, axis=0)], axis=0
            ),
            args,
        )
    run = _compiled(fn, chunk, devices)
    per_dev = padded // n_dev
    # one dispatch per device (asynchronous: they run concurrently), then gather
    outs = [
        run(
            jax.device_put(
                jax.tree.map(lambda x, d=d: x[d * per_dev : (d + 1) * per_dev], args),
                dev,
            )
        )
        for d, dev in enumerate(devices)
    ]
    out = (
        outs[0]
        if n_dev == 1
        else jax.tree.map(
            lambda *ys: jnp.concatenate([jax.device_put(y, devices[0]) for y in ys]),
            *outs,
        )
    )
    if padded != n:
        out = jax.tree.map(lambda y: y[:n], out)
    return out
