"""One process of tests/test_sweep_processes.py: a sweep of cantilever statics.

Usage: python _sweep_worker.py PROCESS_ID N_PROCESSES PORT OUT.npz
"""

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

P = jnp.linspace(0.1, 2.0, 7)  # 7 cases: uneven over 2 processes
tips, codes = sj.sweep(tip_y, P)
(mine, _), (start, stop) = sj.sweep(tip_y, P, gather=False)
np.savez(
    out,
    tips=np.asarray(tips),
    codes=np.asarray(codes),
    mine=np.asarray(mine),
    range=np.asarray([start, stop]),
    processes=jax.process_count(),
)
