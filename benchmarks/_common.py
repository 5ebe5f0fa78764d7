"""Helpers shared by the benchmark scripts (imported from the scripts' own folder)."""

import os
import platform
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

# Warm timings are of programs compiled at XLA's default level from their first call:
# sorojax's default compile tiers would run a program's first calls at -O0 (see
# sorojax.compile_mode). latency.py times the tiers on their own.
os.environ.setdefault("SOROJAX_COMPILE", "full")

# XLA's CPU runtime flags as the examples set them (sorojax.set_runtime_flags), before
# any JAX array exists: a script that started JAX's backend before importing this
# module runs without them (recorded in each result's environment).
import sorojax as _sj  # noqa: E402

_sj.set_runtime_flags()


def git_state():
    """HEAD commit and whether sorojax/ has uncommitted changes, or None without git."""
    try:
        head = subprocess.run(
            ["git", "rev-parse", "HEAD"],
            cwd=ROOT,
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "sorojax"],
            cwd=ROOT,
            capture_output=True,
            text=True,
            check=True,
        ).stdout.rstrip()
        return {"head": head, "sorojax_uncommitted_changes": dirty.splitlines()}
    except (OSError, subprocess.CalledProcessError):
        return None


def environment(**extra):
    """Machine, library versions, load and git state of a run, plus ``extra`` keys.

    Import after ``jax.config.update("jax_enable_x64", ...)``: x64 is read here.
    """
    import equinox as eqx
    import jax

    import sorojax

    return {
        "devices": [str(d) for d in jax.devices()],
        "backend": jax.default_backend(),
        "jax_version": jax.__version__,
        "equinox_version": eqx.__version__,
        "sorojax_version": sorojax.__version__,
        "cpu_count": os.cpu_count(),
        "python": sys.version.split()[0],
        "platform": platform.platform(),
        "processor": platform.processor() or platform.machine(),
        "x64": bool(jax.config.jax_enable_x64),
        "xla_flags": os.environ.get("XLA_FLAGS", ""),
        "load_average_at_start": list(os.getloadavg()),
        "git": git_state(),
    } | extra


def timed(f, *args, repeats, warmup=True):
    """(median, min) wall time [s] of ``f(*args)`` over ``repeats`` blocked calls."""
    import jax

    if warmup:
        jax.block_until_ready(f(*args))
    ts = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(f(*args))
        ts.append(time.perf_counter() - t0)
    return statistics.median(ts), min(ts)


def interleaved_times(calls, repeats):
    """Warm wall times [s] of several variants of one computation, interleaved.

    ``calls`` maps names to zero-argument callables; each is called once to warm
    up, then ``repeats`` rounds call every variant in turn (blocked), so that the
    machine's drift hits them alike. Returns ``{name: [seconds, ...]}``.
    """
    import jax

    for call in calls.values():
        jax.block_until_ready(call())
    times = {name: [] for name in calls}
    for _ in range(repeats):
        for name, call in calls.items():
            t0 = time.perf_counter()
            jax.block_until_ready(call())
            times[name].append(time.perf_counter() - t0)
    return times


def compile_time(jitted, *args):
    """(compiled executable, seconds to trace + lower + compile)."""
    t0 = time.perf_counter()
    compiled = jitted.lower(*args).compile()
    return compiled, time.perf_counter() - t0
