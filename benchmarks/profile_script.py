"""Where a script's first run goes: import, tracing, lowering, XLA compiles, the rest.

Runs a Python script (an example, say) in this process with JAX's compile events
recorded (``jax.monitoring``: the jaxpr trace, the jaxpr -> StableHLO lowering and
the backend compile of every program, by function name), then prints the wall time
split into the import of sorojax, the union of the trace spans (nested traces of
inner jits counted once), of the lowering spans and of the compile spans, and what
is left (computation, Python, figures), with the longest programs of each kind.

Run (the persistent compilation cache off, as a new user's first run)::

    SOROJAX_CACHE_DIR=off .venv/bin/python benchmarks/profile_script.py \
        examples/snap_through.py --out /tmp/x --overwrite [--top 12]
"""

import collections
import runpy
import sys
import time

TOP = 12
EVENTS = {
    "/jax/core/compile/jaxpr_trace_duration": "trace",
    "/jax/core/compile/jaxpr_to_mlir_module_duration": "lower",
    "/jax/core/compile/backend_compile_duration": "compile",
}


def _eager_names():
    """Names of jax.numpy / lax functions (an eager call compiles ``jit(name)``)."""
    import jax.lax
    import jax.numpy as jnp

    names = set(dir(jnp)) | set(dir(jax.lax)) | set(dir(jnp.linalg))
    return names | {
        "stage",
        "broadcast_in_dim",
        "convert_element_type",
        "squeeze",
        "dynamic_slice",
        "scatter",
        "scatter-add",
        "integer_pow",
        "select_n",
        "_where",
        "_einsum",
        "_squeeze",
        "_diag",
        "_reduce_sum",
        "true_divide",
    }


def _union(spans):
    """Total length of the union of ``(start, end)`` intervals."""
    total, end = 0.0, -float("inf")
    for a, b in sorted(spans):
        if b > end:
            total += b - max(a, end)
            end = b
    return total


def main():
    argv = sys.argv[1:]
    top = TOP
    if "--top" in argv:
        i = argv.index("--top")
        top = int(argv[i + 1])
        del argv[i : i + 2]
    script, script_args = argv[0], argv[1:]
    start = time.time()
    import jax
    from jax._src import monitoring

    import sorojax  # noqa: F401  (its import is part of a user's first run)

    imported = time.time()
    spans = collections.defaultdict(list)
    per_fun = collections.defaultdict(float)

    def on_span(event, t0, t1, **kw):
        kind = EVENTS.get(event)
        if kind is not None:
            spans[kind].append((t0, t1))
            per_fun[(kind, kw.get("fun_name", "?"))] += t1 - t0

    monitoring.register_event_time_span_listener(on_span)
    sys.argv = [script, *script_args]
    try:
        runpy.run_path(script, run_name="__main__")
    except SystemExit as e:  # an example's main() may exit
        if e.code not in (None, 0):
            raise
    jax.effects_barrier()
    eager = _eager_names()
    end = time.time()
    total = end - start
    parts = {"import": imported - start}
    for kind in ("trace", "lower", "compile"):
        parts[kind] = _union(spans[kind])
        parts[f"{kind} programs"] = len(spans[kind])
    rest = (
        total - parts["import"] - sum(parts[k] for k in ("trace", "lower", "compile"))
    )
    print(f"\n== {script}: {total:.2f} s in all")
    print(
        "   import {import:.2f} s | trace {trace:.2f} s ({trace programs}) | lower "
        "{lower:.2f} s ({lower programs}) | compile {compile:.2f} s "
        "({compile programs})".format(**parts)
        + f" | rest {rest:.2f} s"
    )
    # programs of one operation (run outside jit, each compiled on first use)
    ops = [
        t
        for (k, f), t in per_fun.items()
        if k == "compile" and f.startswith("jit(") and f[4:-1] in eager
    ]
    print(f"   single operations run eagerly: {len(ops)} compiles, {sum(ops):.2f} s")
    for kind in ("trace", "lower", "compile"):
        rows = sorted(
            ((t, f) for (k, f), t in per_fun.items() if k == kind), reverse=True
        )
        print(f"   {kind}: " + ", ".join(f"{f} {t:.2f}" for t, f in rows[:top]))


if __name__ == "__main__":
    main()
