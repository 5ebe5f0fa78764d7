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

Several processes (``jax.distributed``, one per host or per GPU; on one machine,
``N`` local processes started with :func:`initialize_processes`): each process takes
an even share of the cases (the last ones padded with copies of the last case), runs
it on its own local devices as above, and the outputs are gathered to every process
by ``jax.experimental.multihost_utils.process_allgather``, the only communication
of the sweep (``gather=False`` keeps each process's own rows instead). A
single-process run is unchanged. :func:`process_sum` adds a pytree over the
processes the same way (the gradients of a data-parallel training step).

Checkpoints (``checkpoint=FOLDER``): the cases run in blocks of ``block`` cases, one
block after another, and each finished block's outputs are saved in the folder as
``block_NNNNNN.npz`` (written to a temporary file and moved into place, so a killed
run leaves whole blocks only). A run with the same folder and the same inputs loads
the saved blocks and computes only the missing ones; ``progress(block, n_blocks,
computed)`` is called after each block. The folder's ``sweep.json`` records the
inputs' fingerprint (a SHA-256 of their leaves' bytes, shapes and dtypes), the block
size and the number of cases; a run whose inputs or block size differ stops with an
error instead of mixing or overwriting another sweep's results. Plain NumPy files
rather than orbax: a block is a few arrays written once and read back once, on one
host, and the files open without sorojax or JAX. In a run of several processes each
process checkpoints its own share in ``FOLDER/process_P_of_N`` (``P`` its index,
``N`` the number of processes); a rerun with the same number of processes resumes
each share, and the gather follows.

What it does not do: change the solvers. A vmapped ``solve_statics`` runs its
Newton loop until the slowest case of its chunk converges (converged cases idle in
the loop), and a vmapped ``simulate`` takes the adaptive steps of its
fastest-varying case for the whole chunk; sort or group cases by difficulty when
that matters.
"""

import functools
import hashlib
import json
import os
from collections.abc import Callable, Sequence
from typing import Literal

import jax
import jax.numpy as jnp
import numpy as np

from ._jit import compiler_options
from .io._files import as_path, writing


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


def initialize_processes(
    coordinator_address: str | None = None,
    num_processes: int | None = None,
    process_id: int | None = None,
) -> None:
    """Join a multi-process JAX run (``jax.distributed.initialize``) for sweeps.

    Call it first, before any JAX computation, in every process. With no arguments
    JAX detects the cluster (SLURM, Open MPI, cloud TPU/GPU environments); on one
    machine give ``coordinator_address="localhost:PORT"``, ``num_processes`` and each
    process's ``process_id``. CPU processes gather through gloo, which this sets as
    JAX's CPU collectives backend (GPUs use NCCL, JAX's default).

    Args:
        coordinator_address: ``"host:port"`` of process 0.
        num_processes: how many processes take part.
        process_id: this process's number, 0 to ``num_processes - 1``.
    """
    jax.config.update("jax_cpu_collectives_implementation", "gloo")
    jax.distributed.initialize(
        coordinator_address=coordinator_address,
        num_processes=num_processes,
        process_id=process_id,
    )


def process_sum(tree):
    """Sum a pytree of arrays over the processes of a multi-process run.

    Every process passes a pytree of the same structure, shapes and dtypes (e.g.
    the gradient of its share of a batch) and receives the leaf-wise sum over all
    processes, the same on every process: every process's arrays are gathered
    (``jax.experimental.multihost_utils.process_allgather``, one gather per dtype
    of the leaves) and added in process order on the host. For data-parallel
    training, let each process compute the *summed* loss of its share divided by
    the global batch size: the shares' gradients then add up to the gradient of the
    batch's mean loss, for any split of the batch. In one process the tree is
    returned unchanged (so the same code runs there, inside ``jax.jit`` too).

    Args:
        tree: a pytree of arrays (concrete values: call it outside ``jax.jit`` in a
            run of several processes).

    Returns:
        The pytree of sums (JAX arrays of the leaves' dtypes and shapes).

    Raises:
        TypeError: a leaf is traced (inside ``jit``, ``grad`` or ``vmap``) in a run
            of several processes.

    Example:
        Each process's share of a batch, then the same update everywhere::

            loss, grads = sorojax.process_sum(share_loss_and_grads(params, mine))
    """
    if jax.process_count() == 1:
        return tree
    from jax.experimental import multihost_utils

    leaves, treedef = jax.tree.flatten(tree)
    if any(isinstance(x, jax.core.Tracer) for x in leaves):
        raise TypeError(
            "process_sum: a leaf is traced; in a run of several processes call it "
            "outside jax.jit / grad / vmap, on concrete arrays (e.g. between a "
            "jitted gradient and a jitted update)."
        )
    arrays = [np.asarray(x) for x in leaves]
    sums: list = [None] * len(arrays)
    # one gather per dtype: the leaves of a dtype travel as one flat vector; dtypes
    # in the order of their first leaf, the same on every process (a set's order
    # may differ between processes, and gathers of different sizes would meet)
    for dtype in dict.fromkeys(a.dtype for a in arrays):
        which = [i for i, a in enumerate(arrays) if a.dtype == dtype]
        flat = np.concatenate([arrays[i].ravel() for i in which])
        total = np.sum(multihost_utils.process_allgather(flat), axis=0)
        cuts = np.cumsum([arrays[i].size for i in which])[:-1]
        for i, part in zip(which, np.split(total, cuts), strict=True):
            sums[i] = jnp.asarray(part.reshape(arrays[i].shape), dtype=dtype)
    return jax.tree.unflatten(treedef, sums)


def _fingerprint(args, block: int) -> dict:
    """What identifies a checkpointed sweep: its inputs, the block size, the count."""
    h = hashlib.sha256()
    leaves, treedef = jax.tree.flatten(args)
    h.update(str(treedef).encode())
    for x in leaves:
        a = np.ascontiguousarray(np.asarray(x))
        h.update(f"{a.dtype.str}{a.shape}".encode())
        h.update(a.tobytes())
    return {
        "inputs_sha256": h.hexdigest(),
        "block": int(block),
        "cases": _batch_size(args),
    }


def _open_checkpoint(folder, args, block: int):
    """The checkpoint folder, created or checked against this sweep's fingerprint."""
    folder = as_path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    meta = _fingerprint(args, block)
    path = folder / "sweep.json"
    if path.exists():
        saved = json.loads(path.read_text())
        if saved != meta:
            what = [k for k in meta if saved.get(k) != meta[k]]
            raise ValueError(
                f"sweep: checkpoint = {str(folder)!r} holds another sweep (its "
                f"{', '.join(what)} differ: saved {[saved.get(k) for k in what]}, "
                f"now {[meta[k] for k in what]}); its results were left unchanged. "
                "Give a new folder, or delete this one to start over."
            )
    else:
        with writing(path, overwrite=False) as tmp:
            tmp.write_text(json.dumps(meta, indent=1) + "\n")
    return folder


def _save_block(path, out) -> None:
    leaves = jax.tree.leaves(out)
    with writing(path, overwrite=False) as tmp:
        with open(tmp, "wb") as f:
            np.savez(f, *[np.asarray(x) for x in leaves])


def _load_block(path, treedef):
    with np.load(path) as data:
        leaves = [data[f"arr_{i}"] for i in range(len(data.files))]
    if len(leaves) != treedef.num_leaves:
        raise ValueError(
            f"sweep: {str(path)!r} holds {len(leaves)} arrays where the function "
            f"returns {treedef.num_leaves}: it was written by another function; "
            "give a new checkpoint folder."
        )
    return jax.tree.unflatten(treedef, [jnp.asarray(x) for x in leaves])


def sweep(
    fn: Callable,
    *args,
    chunk: int | Literal["auto"] | None = "auto",
    devices: Sequence[jax.Device] | None = None,
    checkpoint: str | os.PathLike | None = None,
    block: int | None = None,
    progress: Callable[[int, int, bool], None] | None = None,
    gather: bool = True,
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
        devices: the devices to use (default ``jax.devices()``, or in a run of
            several processes each process's ``jax.local_devices()``).
        checkpoint: a folder: save each finished block of cases there, and load
            the blocks a former run with the same inputs saved (module notes; with
            several processes, one subfolder per process).
        block: cases per saved block (default: 64 passes of every device, at
            most all the cases); only with ``checkpoint``.
        progress: called as ``progress(block, n_blocks, computed)`` after each
            block with ``checkpoint`` (``computed`` False: loaded from the folder).
        gather: in a run of several processes, gather every process's outputs to
            every process (default); False returns ``(rows, (start, stop))``: this
            process's outputs and the cases they belong to (in one process, all of
            them: the same script runs on one process or several).

    Returns:
        ``fn``'s outputs stacked along a leading axis, one row per case (on the
        first device).

    Raises:
        ValueError: no cases, leading axes that differ, ``chunk`` or ``block`` <
            1, or a checkpoint folder that holds another sweep.

    Example:
        On a CPU, set ``XLA_FLAGS=--xla_force_host_platform_device_count=2`` (one
        device per core) before JAX starts, then::

            tips = sorojax.sweep(tip_of_load, jnp.linspace(0.0, 10.0, 1024))
    """
    n_proc = jax.process_count()
    if n_proc > 1 and devices is None:
        return _across_processes(fn, args, chunk, checkpoint, block, progress, gather)
    if not gather:  # one process holds every row
        out = sweep(fn, *args, chunk=chunk, devices=devices, checkpoint=checkpoint,
                    block=block, progress=progress)  # fmt: skip
        return out, (0, _batch_size(args))
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
    if checkpoint is None:
        if block is not None or progress is not None:
            raise ValueError(
                "sweep: block and progress apply to checkpointed sweeps only; give "
                "checkpoint=FOLDER too, or leave them out."
            )
        return _run(fn, args, n, chunk, devices, per_pass)
    if block is None:
        block = min(64 * per_pass, n)
    if int(block) < 1:
        raise ValueError(f"sweep: block = {block}; give a positive number of cases.")
    block = int(block)
    folder = _open_checkpoint(checkpoint, args, block)
    n_blocks = -(-n // block)
    one = jax.tree.map(lambda x: x[:1], args)
    treedef = jax.tree.structure(jax.eval_shape(jax.vmap(fn), *one))
    parts = []
    for b in range(n_blocks):
        path = folder / f"block_{b:06d}.npz"
        computed = not path.exists()
        if computed:
            part = jax.tree.map(lambda x, b=b: x[b * block : (b + 1) * block], args)
            out = _run(fn, part, _batch_size(part), chunk, devices, per_pass)
            _save_block(path, out)
        else:
            out = _load_block(path, treedef)
        parts.append(out)
        if progress is not None:
            progress(b, n_blocks, computed)
    if n_blocks == 1:
        return parts[0]
    return jax.tree.map(lambda *ys: jnp.concatenate(ys), *parts)


def _across_processes(fn, args, chunk, checkpoint, block, progress, gather):
    """``sweep`` in a run of several processes (module notes)."""
    from jax.experimental import multihost_utils

    n = _batch_size(args)
    if n == 0:
        raise ValueError("sweep: no cases (the leading axis has length 0).")
    p, n_proc = jax.process_index(), jax.process_count()
    share = -(-n // n_proc)
    start, stop = min(p * share, n), min((p + 1) * share, n)
    # every process runs `share` cases (shapes agree for the gather): its own, padded
    # with copies of the last case (all copies for a process past the end)
    idx = np.minimum(np.arange(start, start + share), n - 1)
    mine = jax.tree.map(lambda x: jnp.asarray(x)[idx], args)
    if checkpoint is not None:  # each process its own share's folder
        checkpoint = as_path(checkpoint) / f"process_{p}_of_{n_proc}"
    # (block or progress without a checkpoint are refused there, as in one process)
    out = sweep(
        fn, *mine, chunk=chunk, devices=jax.local_devices(), checkpoint=checkpoint,
        block=block, progress=progress,
    )  # fmt: skip
    if not gather:
        return jax.tree.map(lambda y: y[: stop - start], out), (start, stop)
    rows = multihost_utils.process_allgather(out, tiled=True)
    return jax.tree.map(lambda y: jnp.asarray(y[:n]), rows)


def _run(fn, args, n: int, chunk, devices, per_pass: int):
    """One pass of ``sweep`` over ``n`` cases (no checkpoint)."""
    n_dev = len(devices)
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
