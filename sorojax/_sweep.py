"""Batched parameter sweeps sharded over every device JAX sees.

``sweep(fn, *args)`` is ``jax.vmap(fn)(*args)`` compiled once, with the batch split
evenly over ``jax.devices()`` (GPUs of a multi-GPU host; on a CPU, the host
devices that ``XLA_FLAGS=--xla_force_host_platform_device_count=N`` creates, one
per core). Each device runs its share as an independent program (one asynchronous
dispatch per device, compiled once per device, every share placed before the first
dispatch), so a solver loop ends per device, without collectives: a sharded ``jit``
of the same vmap kept the loops global and stalled on 2 CPU host devices at 1024
cases, and ``pmap`` / ``shard_map`` trip lineax's structure check inside the
statics solve (sharded abstract values) in JAX 0.10. Each device runs its cases in
chunks of ``chunk``, one after another (``lax.map`` over chunks): each chunk's
loops end with its own slowest case, and memory stays bounded for very large
sweeps on an accelerator. The default, ``"auto"``, is 8 cases per chunk on CPU
devices (a vmapped Newton loop runs until its slowest case converges and a
vmapped Jacobian gains nothing from the batch axis on a CPU core, while vmapped
Rosenbrock steps do; 8 was the best common size for the four-cable arm's statics
and dynamics, ``benchmarks/sweeps.py``) and the whole share at once on other
backends.

Several CPU host devices and large chunks: jaxlib 0.10's batched LAPACK kernels
(LU, Cholesky, eigh; used by every linear solve) split a large batch over the CPU
thread pool and block waiting for it; two devices doing so at the same time
deadlock. Measured on 2 host devices with batched LU: 2^14 matrix entries per call
ran (256 8 x 8 or 16 32 x 32 systems), 2^15 deadlocked (512 8 x 8 or 16 64 x 64;
the 8-DoF arm's statics unchunked at 1024 cases). Keep ``chunk x n^2`` at most
2^14 on CPU host devices (the default does for up to 45 coordinates).

The batch is padded to a whole number of chunks with copies of its last case and
the padding is dropped from the result.

What it does not do: change the solvers. A vmapped ``solve_statics`` runs its
Newton loop until the slowest case of its chunk converges (converged cases idle in
the loop), and a vmapped ``simulate`` takes the adaptive steps of its
fastest-varying case for the whole chunk; sort or group cases by difficulty when
that matters.
"""

import functools
from collections.abc import Callable, Sequence
from typing import Literal

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


# Cases per chunk on CPU devices (benchmarks/sweeps.py, 2 host devices, four-cable
# arm, throughput over one call per case: statics at chunks of 1 / 4 / 8 / 16 ->
# 3.46 / 3.28 / 3.29 / 3.06-3.10x, dynamics 2.72 / 3.68 / 4.62 / 4.99-5.24x). Small
# chunks also keep every batched LAPACK call small (module notes: deadlock of two
# CPU devices in jaxlib 0.10's threaded batched LAPACK).
_CPU_CHUNK = 8


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
    chunk: int | Literal["auto"] | None = "auto",
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
        chunk: cases per device per pass: a number, None (all of a device's
            share at once) or ``"auto"`` (8 on CPU devices, at most the share;
            all at once on other backends).
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
    n_dev = len(devices)
    if isinstance(chunk, str):
        if chunk != "auto":
            raise ValueError(
                f"sweep: chunk = {chunk!r}; give a positive number of cases, None "
                "(all at once) or 'auto'."
            )
        cpu = all(d.platform == "cpu" for d in devices)
        chunk = min(_CPU_CHUNK, -(-n // n_dev)) if cpu else None
    if chunk is not None and chunk < 1:
        raise ValueError(f"sweep: chunk = {chunk}; give a positive number of cases.")
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
    # Every device's share is cut and placed before any program is dispatched: a
    # slice queued on a device behind that device's running sweep waits for it,
    # which ran the devices one after another (2 CPU host devices: 184 ms instead
    # of 90 ms for 256 statics cases).
    shares = [
        jax.device_put(
            jax.tree.map(lambda x, d=d: x[d * per_dev : (d + 1) * per_dev], args),
            dev,
        )
        for d, dev in enumerate(devices)
    ]
    jax.block_until_ready(shares)
    # one dispatch per device (asynchronous: they run concurrently), then gather
    outs = [run(share) for share in shares]
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
