"""One process of tests/test_sweep_processes.py: a sweep of statics.

Usage: python _sweep_worker.py PROCESS_ID N_PROCESSES PORT OUT.npz [arm | FOLDER]

Seven cantilever loads, or with ``arm`` 256 random tension sets of the four-cable
arm (``benchmarks/sweeps.py``'s statics cases). With a FOLDER the cantilever sweep
also runs checkpointed there in blocks of 2 cases, then again after this process's
last block file is deleted (a run killed before it): the blocks each run computed
are saved as ``computed_1`` and ``computed_2``.
"""

import pathlib
import sys

import jax

import sorojax as sj

pid, n_proc, port, out = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3], sys.argv[4]
if n_proc > 1:
    sj.initialize_processes(f"localhost:{port}", n_proc, pid)
jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
from test_sweep import _tip_y as tip_y  # noqa: E402  (the same cases as test_sweep)

if sys.argv[5:] == ["arm"]:
    from sorojax._mechanisms import cable_manipulator

    ARM = cable_manipulator(order=1, eta=3e4)

    def case(T):
        sol = sj.solve_statics(ARM, u=T, throw=False)
        return sj.tip_pose(ARM, sol.q)[:3, 3], sol.result._value

    P = 10.0 * jax.random.uniform(jax.random.key(0), (256, 4))
else:
    case = tip_y
    P = jnp.linspace(0.1, 2.0, 7)  # 7 cases: uneven over 2 processes
tips, codes = sj.sweep(case, P)
(mine, _), (start, stop) = sj.sweep(case, P, gather=False)
extra = {}
if sys.argv[5:] and sys.argv[5] != "arm":
    folder = pathlib.Path(sys.argv[5])
    for run in (1, 2):
        done = []
        t, _ = sj.sweep(
            case,
            P,
            checkpoint=folder,
            block=2,
            progress=lambda b, n, c, done=done: done.append(c),
        )
        extra[f"tips_{run}"] = np.asarray(t)
        extra[f"computed_{run}"] = np.asarray(done)
        if run == 1:  # this process's last block is lost
            mine_dir = folder / f"process_{jax.process_index()}_of_{n_proc}"
            if n_proc == 1:
                mine_dir = folder
            sorted(mine_dir.glob("block_*.npz"))[-1].unlink()
np.savez(
    out,
    tips=np.asarray(tips),
    codes=np.asarray(codes),
    mine=np.asarray(mine),
    range=np.asarray([start, stop]),
    processes=jax.process_count(),
    **extra,
)
