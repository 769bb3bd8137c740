"""``hamrkq compile``: the compiled code in the cache before its first use.

A first use compiles the step kernel (once per hamrkq version and machine,
10-15 s) and the system's functions (from a fraction of a second to several
seconds for the outer solar system), in the background while the run starts
interpreted (:mod:`hamrkq.backends.background`).  This command does it ahead:
for a container image, a shared installation or a cluster's nodes, so that
every later run loads the code from the cache (``HAMRKQ_CACHE_DIR``,
``NUMBA_CACHE_DIR``).  It prints one line per item with what it did and
how long it took.
"""

from __future__ import annotations

import argparse
import time
from typing import Any

from hamrkq.catalogue.problems import list_problems, load_problem
from hamrkq.errors import OptionError

__all__ = ["compile_command", "register"]


def register(subparsers: Any) -> None:
    """Add the ``compile`` subcommand."""
    p = subparsers.add_parser(
        "compile",
        help="compile the step kernel and systems into the cache ahead of their first use",
        description=(
            "Compile the RKQ step kernel and the functions of each NAME|FILE into the "
            "cache, or load them if they are there, so that later runs start compiled."
        ),
    )
    p.add_argument(
        "problems",
        nargs="*",
        metavar="NAME|FILE",
        help="catalogue names or .toml files (none: the kernel only)",
    )
    p.add_argument("--all", action="store_true", help="every problem of the catalogue")
    p.set_defaults(func=compile_command)


def compile_command(args: argparse.Namespace) -> int:
    """Run the ``compile`` subcommand; returns the exit status.

    Raises
    ------
    OptionError
        The compiled backend cannot be used here (the reason is named).
    """
    from hamrkq.backends import codegen, compiled, first_use, kernel_helper
    from hamrkq.backends import kernel as kernel_module
    from hamrkq.backends.numba_compile import available

    ok, reason = available()
    if not ok:
        raise OptionError(f"nothing can be compiled: {reason}")
    names = list_problems() if args.all else list(args.problems)
    problems = [load_problem(name) for name in names]  # every name checked first
    print(f"cache: {codegen.cache_dir()}", flush=True)
    # The kernel (10-15 s) compiles in a helper process on another core while
    # this one compiles the systems.
    started = time.perf_counter()
    helper = kernel_helper.start_kernel_helper() if problems else None
    if helper is None:
        _timed("the step kernel", kernel_module.build_kernel)
    for problem in problems:
        # Every function, those a run compiles on demand too (jac, rhs_jvp).
        _timed(
            problem.name, lambda p=problem: compiled.compile_system(p.hamiltonian).compile_all()
        )
    if helper is not None:
        kernel_helper.join_helper(helper)
        elapsed = time.perf_counter() - started
        if helper.returncode == 0:
            print(f"the step kernel: compiled in a helper process ({elapsed:.1f} s)", flush=True)
        else:  # compiled below, in this process
            print("the step kernel: the helper process failed; compiling it here", flush=True)
    for problem in problems:
        # Each system with the kernel, one step: loads what is cached (or
        # compiles what the helper did not) and proves that they work together.
        first_use.warm_up(problem.hamiltonian, announce=False)
    return 0


def _timed(label: str, work: Any) -> None:
    """Run ``work`` and say whether it compiled or only loaded, and how long it took."""
    from hamrkq.backends import compiled

    before = compiled.COMPILE_COUNT
    started = time.perf_counter()
    work()
    elapsed = time.perf_counter() - started
    done = compiled.COMPILE_COUNT - before
    what = f"compiled {done} function(s)" if done else "already in the cache"
    print(f"{label}: {what} ({elapsed:.1f} s)", flush=True)
