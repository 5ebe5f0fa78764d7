"""sorojax's compiled entry points: ``eqx.filter_jit`` with XLA options of its own.

sorojax's programs are many small fusions and matrix products (6 x 6 adjoints, a
few dozen coordinates). On CPU, XLA's classic (LLVM IR) emitters compile them 20-35%
faster than its newer fusion emitters and run them as fast or faster (the hybrid
scene's dynamics ~30% faster), so sorojax compiles its own programs with
``xla_cpu_use_fusion_emitters = False`` (`benchmarks/xla_options.py`, figures in
benchmarks/README.md). Same arithmetic: results agree to rounding (tested).

The options are probed once, on the first compile: a JAX whose XLA does not know
them, a backend other than CPU, or ``SOROJAX_XLA_OPTIONS=off`` compiles with XLA's
defaults. JAX takes compiler options on top-level jits only: a sorojax call inside
your own ``jax.jit``, ``grad`` or ``vmap`` is compiled with the outer program's
options; pass ``compiler_options=sorojax.compiler_options()`` to your top-level
``jax.jit`` to get these.
"""

import functools
import os
from collections.abc import Callable
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp

CPU_OPTIONS: dict[str, Any] = {"xla_cpu_use_fusion_emitters": False}


def compiler_options() -> dict[str, Any]:
    """XLA options sorojax compiles its programs with (a fresh dict each call).

    ``{"xla_cpu_use_fusion_emitters": False}`` on CPU when this XLA knows it, else
    ``{}`` (other backends, older or newer XLA, ``SOROJAX_XLA_OPTIONS=off``). Use it
    for your own jit around sorojax calls::

        jax.jit(f, compiler_options=sorojax.compiler_options())
    """
    return dict(_probed_options())


@functools.cache
def _probed_options() -> dict[str, Any]:
    if os.environ.get("SOROJAX_XLA_OPTIONS", "").lower() == "off":
        return {}
    if jax.default_backend() != "cpu":
        return {}
    try:
        probe = jax.jit(lambda x: jnp.sin(x) + x, compiler_options=CPU_OPTIONS)
        probe.lower(jnp.zeros(3)).compile()
    except Exception:  # noqa: BLE001 - an XLA without the option: use its defaults
        return {}
    return dict(CPU_OPTIONS)


try:  # private: a JAX without it gets XLA's defaults everywhere
    from jax._src.core import trace_state_clean as _trace_state_clean
except ImportError:  # pragma: no cover
    _trace_state_clean = None


def _top_level() -> bool:
    """No JAX trace active (JAX accepts compiler options on top-level jits only)."""
    return _trace_state_clean is not None and _trace_state_clean()


def jit(fun: Callable) -> Callable:
    """``eqx.filter_jit(fun)``, compiled with :func:`compiler_options` at top level.

    Called inside another trace (your ``jit``, ``grad``, ``vmap``), the function is
    the plain ``eqx.filter_jit(fun)``: JAX takes compiler options on top-level jits
    only, and there the outer program's options apply. The options are probed on the
    first top-level call (not at import, which must not start a JAX backend).
    """
    plain = eqx.filter_jit(fun)
    tuned: list = []

    def pick():
        if not _top_level():
            return plain
        if not tuned:
            opts = _probed_options()
            tuned.append(eqx.filter_jit(fun, compiler_options=opts) if opts else plain)
        return tuned[0]

    @functools.wraps(fun)
    def call(*args, **kwargs):
        return pick()(*args, **kwargs)

    # ahead-of-time compilation, as on a filter_jit: f.lower(*args).compile()
    call.lower = lambda *args, **kwargs: pick().lower(*args, **kwargs)
    return call
