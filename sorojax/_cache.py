"""JAX's persistent compilation cache for scripts (examples, the command line).

Compiling a closed-loop model's statics or dynamics takes seconds to tens of seconds
on a small CPU; the tracing that precedes it (a few seconds) cannot be cached, the
compiled programs can. sorojax's compiled cores hold no host callback (a program
with one is never cached), so a second run of a script loads them from disk.
"""

import os
import pathlib

import jax


def default_cache_dir() -> pathlib.Path:
    """``$SOROJAX_CACHE_DIR``, else ``$XDG_CACHE_HOME/sorojax/jax`` (``~/.cache``)."""
    env = os.environ.get("SOROJAX_CACHE_DIR")
    if env:
        return pathlib.Path(env).expanduser()
    xdg = os.environ.get("XDG_CACHE_HOME") or str(pathlib.Path.home() / ".cache")
    return pathlib.Path(xdg).expanduser() / "sorojax" / "jax"


def enable_compilation_cache(
    path: str | os.PathLike | None = None, min_compile_time: float = 0.0
) -> pathlib.Path | None:
    """Keep compiled programs on disk so that later runs skip the compile.

    A thin wrapper over JAX's options ``jax_compilation_cache_dir`` and
    ``jax_persistent_cache_min_compile_time_secs``. Call it once, before the first
    compile. A cache directory already set (``JAX_COMPILATION_CACHE_DIR`` or
    ``jax.config``) is kept; ``SOROJAX_CACHE_DIR=off`` turns the cache off. Entries
    are keyed by a hash of the program, the JAX version and the device, so a stale
    entry is never used; delete the folder to reclaim the space.

    Args:
        path: the cache folder (default :func:`default_cache_dir`).
        min_compile_time: programs that compile faster than this [s] are not stored
            (default 0: all; the single operations a script runs outside jit each
            compile in ~30 ms and load in a few, which saved ~4 s of the manual
            hybrid example's second run).

    Returns:
        The folder in use, or None when the cache is off.
    """
    if os.environ.get("SOROJAX_CACHE_DIR", "").lower() == "off":
        return None
    current = jax.config.jax_compilation_cache_dir
    if current:
        return pathlib.Path(current)
    folder = pathlib.Path(path).expanduser() if path else default_cache_dir()
    jax.config.update("jax_compilation_cache_dir", str(folder))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", min_compile_time)
    return folder
