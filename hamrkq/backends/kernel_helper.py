"""The helper process that compiles the step kernel during a first use.

On a first use of a large system (:data:`HELPER_MIN_DIM` state variables or
more) with no kernel in the cache, a helper process compiles the kernel into
the cache (:func:`hamrkq.backends.kernel.build_kernel`) while the calling
process prepares the system on another core (:func:`start_helper`,
:func:`join_helper`); ``hamrkq compile`` starts one too
(:func:`start_kernel_helper`), and :mod:`hamrkq.backends.background` starts
its helpers with :func:`spawn_helper`.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from hamrkq.backends.kernel import kernel_cached

__all__ = [
    "HELPER_MIN_DIM",
    "HELPER_TIMEOUT",
    "cores",
    "join_helper",
    "spawn_helper",
    "start_helper",
    "start_kernel_helper",
]

#: Systems of at least this many state variables have the kernel compiled by
#: a helper process while they are prepared, on a first use (measured, empty
#: cache: outer_solar_system, 36, 19.9-20.9 s -> 13.8-14.7 s; prentice2011, 2,
#: 11.7-13.3 s -> 15.6 s, since the helper's own start-up, about 1.5 s, is
#: more than a small system's preparation).
HELPER_MIN_DIM = 12

#: The longest wait for the helper process; after it the helper is stopped
#: and the calling process compiles the kernel itself.
HELPER_TIMEOUT = 600.0


def start_helper(dim: int) -> subprocess.Popen | None:
    """Start compiling the kernel into the cache in a helper process, when it
    is not there, the system is large (:data:`HELPER_MIN_DIM`) and a second
    core can do it while this process derives, generates and compiles the
    system (outer_solar_system's takes about 6 s beside the kernel's 12 s);
    None otherwise, or if the helper cannot be started."""
    return start_kernel_helper() if dim >= HELPER_MIN_DIM else None


def start_kernel_helper() -> subprocess.Popen | None:
    """A helper process compiling the kernel into the cache
    (:func:`hamrkq.backends.kernel.build_kernel`) when it is not there and a
    second core can take it; None otherwise."""
    if cores() < 2 or kernel_cached():
        return None
    return spawn_helper("from hamrkq.backends import kernel; kernel.build_kernel()")


def cores() -> int:
    """The cores this process may run on."""
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1


def spawn_helper(code: str) -> subprocess.Popen | None:
    """A Python process running ``code`` with this hamrkq importable, its
    output discarded; None if it cannot be started."""
    env = dict(os.environ)
    root = str(Path(__file__).resolve().parents[2])  # the folder holding hamrkq/
    env["PYTHONPATH"] = os.pathsep.join(p for p in (root, env.get("PYTHONPATH")) if p)
    try:
        return subprocess.Popen(
            [sys.executable, "-c", code],
            env=env,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
    except OSError:
        return None


def join_helper(helper: subprocess.Popen | None) -> None:
    """Wait for the helper; whatever it did, the kernel's own call then loads
    the kernel from the cache or, if the helper failed, compiles it here."""
    if helper is None:
        return
    try:
        helper.wait(timeout=HELPER_TIMEOUT)
    except subprocess.TimeoutExpired:
        helper.kill()
        helper.wait()
