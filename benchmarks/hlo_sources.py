"""Where a compiled program's size and XLA's compile time come from, by source line.

Compiles one target of ``benchmarks/latency.py`` (a top-level ``jax.jit`` with
sorojax's compiler options, cache off) with XLA's dump on, and prints

* XLA's compile split into its phases (JAX's profiler around ``compile()``: HLO
  passes before and after layout assignment, the heaviest single passes, LLVM code
  generation; the phases nest: ``simplification`` and its loop passes run inside the
  HLO passes, and ``TaskDispatcher::dispatch`` sums code generation's tasks over the
  threads that ran them);
* the optimised program's instructions (fused computations included; parameters,
  constants, tuples and bitcasts left out) attributed to the innermost frame in
  ``sorojax/`` of each instruction's stack (XLA writes a table of stack frames into
  the dump; an instruction names its frame), by function and by line.

XLA's CPU fusion copies cheap producers (chains of multiplications and additions)
into every consumer, so an expression used in several places counts several
times: the counts are what XLA compiles, not what the source traces.

Run::

    .venv/bin/python benchmarks/hlo_sources.py statics30 [--top 25]

(targets: those of ``latency.py``).
"""

import argparse
import collections
import glob
import os
import pathlib
import re
import sys
import tempfile
import time

SKIP = {"parameter", "constant", "get-tuple-element", "tuple", "bitcast"}
PHASES = (
    "HLO passes through layout assignment",
    "HLO passes after layout assignment",
    "simplification",
    "simplify-while-loops",
    "while-loop-invariant-code-motion",
    "copy-insertion",
    "SplitModule",
    "Codegen",
    "TaskDispatcher::dispatch",
)


def _frame_tables(lines):
    """``(files, functions, locations, frames)`` from a dumped module's header."""
    tables = {k: {} for k in ("FileNames", "FunctionNames", "FileLocations")}
    frames, section = {}, None
    for line in lines:
        s = line.strip()
        if s in tables or s == "StackFrames":
            section = s
            continue
        if section is None:
            continue
        if not s:
            section = None
            continue
        key, rest = s.split(" ", 1)
        if section in ("FileNames", "FunctionNames"):
            tables[section][int(key)] = rest.strip('"')
        elif section == "FileLocations":
            tables[section][int(key)] = dict(re.findall(r"(\w+)=(\d+)", rest))
        else:
            d = dict(re.findall(r"(\w+)=(\d+)", rest))
            frames[int(key)] = (
                int(d["file_location_id"]),
                int(d.get("parent_frame_id", 0)),
            )
    return tables["FileNames"], tables["FunctionNames"], tables["FileLocations"], frames


def attribute(path):
    """Instruction counts of a dumped optimised module: ``(total, by_fun, by_line)``."""
    lines = pathlib.Path(path).read_text().splitlines()
    files, funs, locs, frames = _frame_tables(lines)

    def innermost_sorojax(fid):
        seen = set()
        while fid in frames and fid not in seen:
            seen.add(fid)
            loc, parent = frames[fid]
            d = locs[loc]
            name = files[int(d["file_name_id"])]
            if "/sorojax/" in name:
                short = name.split("/sorojax/")[-1]
                return short, funs[int(d["function_name_id"])], int(d["line"])
            if parent == fid:
                break
            fid = parent
        return None

    total, by_fun, by_line = 0, collections.Counter(), collections.Counter()
    for line in lines:
        m = re.search(r"=\s*\S+\s+([\w-]+)\(", line)
        if not m or m.group(1) in SKIP:
            continue
        total += 1
        f = re.search(r"stack_frame_id=(\d+)", line)
        where = innermost_sorojax(int(f.group(1))) if f else None
        if where is None:
            by_fun["(outside sorojax)"] += 1
            continue
        short, fun, lineno = where
        by_fun[f"{short} {fun}"] += 1
        by_line[f"{short}:{lineno} {fun}"] += 1
    return total, by_fun, by_line


def _phases(trace_dir):
    """Summed durations of XLA's compile phases from a profiler trace."""
    from jax._src.lib import _profile_data

    (path,) = glob.glob(f"{trace_dir}/**/*.xplane.pb", recursive=True)[-1:]
    data = _profile_data.ProfileData.from_file(path)
    total = collections.Counter()
    for plane in data.planes:
        for line in plane.lines:
            for ev in line.events:
                for phase in PHASES:
                    if ev.name == phase or ev.name.startswith(phase + " ("):
                        total[phase] += ev.duration_ns / 1e9
    return total


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("target", help="a target of latency.py, e.g. statics30")
    ap.add_argument("--top", type=int, default=25, help="rows per table")
    args = ap.parse_args(argv)
    dump = tempfile.mkdtemp(prefix="sorojax-hlo-")
    os.environ["XLA_FLAGS"] = (
        os.environ.get("XLA_FLAGS", "") + f" --xla_dump_to={dump}"
    ).strip()
    sys.path.insert(0, str(pathlib.Path(__file__).parent))
    import latency  # noqa: E402  (imports JAX: after XLA_FLAGS is set)

    jax, sj, f, fargs, _ = latency.start(args.target)
    lowered = jax.jit(f, compiler_options=sj.compiler_options()).trace(*fargs).lower()
    trace_dir = tempfile.mkdtemp(prefix="sorojax-prof-")
    jax.profiler.start_trace(trace_dir)
    start = time.perf_counter()
    lowered.compile()
    seconds = time.perf_counter() - start
    jax.profiler.stop_trace()
    phases = _phases(trace_dir)
    print(f"== {args.target}: XLA compile {seconds:.2f} s")
    for phase in PHASES:
        if phase in phases:
            print(f"   {phases[phase]:7.3f} s  {phase}")
    modules = glob.glob(f"{dump}/*.cpu_after_optimizations.txt")
    biggest = max(modules, key=os.path.getsize)
    total, by_fun, by_line = attribute(biggest)
    print(f"\n{total} instructions in {pathlib.Path(biggest).name}; by function:")
    for key, n in by_fun.most_common(args.top):
        print(f"   {n:6d} {100 * n / total:5.1f} %  {key}")
    print("by line:")
    for key, n in by_line.most_common(args.top):
        print(f"   {n:6d} {100 * n / total:5.1f} %  {key}")
    print(f"(dump: {dump})")


if __name__ == "__main__":
    main()
