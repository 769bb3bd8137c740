"""Where a compiled run's time goes, by function, with Linux ``perf``.

    perf record -F 2000 -o perf.data python benchmarks/profile_kernel.py prentice2011
    perf report -i perf.data --no-children --sort dso,sym

numba's machine code lives in anonymous memory that ``perf`` cannot name.
This script compiles the kernel and the problem's functions in this process
(in temporary caches, so that nothing is loaded from disk), writes
``/tmp/perf-<pid>.map`` (the format ``perf`` reads for just-in-time code:
start, size and name of every compiled function, numba's mangled names
shortened to ``module.function``), and then repeats ``solve`` so that the
run dominates the samples.  Functions that LLVM inlined are counted in their
caller (the stage sums in ``steps.explicit_increment``, for instance).

Options: ``--method``, ``--atol``, ``--rtol`` (default: the problem's own),
``--repeat`` (default 60).  Compilation is part of the profile too (in
``libllvmlite`` and the interpreter); restrict the report to ``--dsos`` of
the JIT code and ``libm`` to see the run alone.  Measured on prentice2011
with ``method="auto"`` at atol 1e-6 (docs/performance.md).
"""

from __future__ import annotations

import argparse
import gc
import os
import re
import sys
import tempfile
import time
import warnings
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def short_name(mangled: str) -> str:
    """The length-prefixed parts of an Itanium-style mangled name before
    numba's ``B`` suffix, joined by dots: ``_ZN6hamrkq3rkq5steps18explicit_incrementB3v54...``
    is ``hamrkq.rkq.steps.explicit_increment``."""
    if not mangled.startswith("_ZN"):
        return mangled
    parts, rest = [], mangled[3:]
    while rest and rest[0].isdigit():
        match = re.match(r"(\d+)", rest)
        size = int(match.group(1))
        start = len(match.group(1))
        parts.append(rest[start : start + size])
        rest = rest[start + size :]
    return ".".join(parts) or mangled


def write_perf_map() -> int:
    """Write ``/tmp/perf-<pid>.map`` for every compiled function of every
    numba dispatcher in this process.  Returns the number of functions."""
    from numba.core.dispatcher import Dispatcher

    entries = []
    for dispatcher in [o for o in gc.get_objects() if isinstance(o, Dispatcher)]:
        for compiled in dispatcher.overloads.values():
            library = compiled.library
            module = getattr(library, "_final_module", None)
            if module is None:  # loaded from a cache: no module to list
                continue
            for function in module.functions:
                if function.is_declaration:
                    continue
                address = library.get_pointer_to_function(function.name)
                if address:
                    entries.append((address, short_name(function.name)))
    entries.sort()
    with open(f"/tmp/perf-{os.getpid()}.map", "w") as out:
        for i, (address, name) in enumerate(entries):
            # perf needs a size: up to the next function (code is laid out
            # in order within one allocation), a page for the last.
            size = entries[i + 1][0] - address if i + 1 < len(entries) else 4096
            out.write(f"{address:x} {size:x} {name}\n")
    return len(entries)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("problem")
    parser.add_argument("--method", default="auto")
    parser.add_argument("--atol", type=float, default=None)
    parser.add_argument("--rtol", type=float, default=None)
    parser.add_argument("--repeat", type=int, default=60)
    args = parser.parse_args()
    caches = tempfile.mkdtemp(prefix="hamrkq-profile-")
    os.environ.update(
        HAMRKQ_CACHE_DIR=f"{caches}/hamrkq",
        NUMBA_CACHE_DIR=f"{caches}/numba",
        HAMRKQ_COMPILE="wait",
    )
    sys.path.insert(0, str(ROOT))
    warnings.simplefilter("ignore")
    import hamrkq
    from hamrkq.backends import kernel_helper

    # A large system's kernel is compiled by a helper process and loaded from
    # the cache, which leaves no module to map: compile it here.
    kernel_helper.HELPER_MIN_DIM = sys.maxsize
    problem = hamrkq.load_problem(args.problem)
    options = {"method": args.method}
    if args.atol is not None:
        options["atol"] = args.atol
    if args.rtol is not None:
        options["rtol"] = args.rtol
    sol = hamrkq.solve(problem, **options)  # compiles everything, in this process
    count = write_perf_map()
    start = time.perf_counter()
    for _ in range(args.repeat):
        sol = hamrkq.solve(problem, **options)
    elapsed = time.perf_counter() - start
    print(
        f"{count} compiled functions mapped in /tmp/perf-{os.getpid()}.map; "
        f"{args.repeat} runs of {args.problem} ({sol.method}, {sol.stats['nfev']} evaluations) "
        f"in {elapsed:.2f} s",
        file=sys.stderr,
    )


if __name__ == "__main__":
    main()
