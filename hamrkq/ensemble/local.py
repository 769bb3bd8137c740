"""Running an ensemble's chunks on this machine: in this thread, a thread pool
or a process pool, and collecting the chunk results into one ensemble.

Threads share the compiled kernel (it is compiled with ``nogil=True``, so
members integrate in parallel), but the Python part of each :func:`hamrkq.solve`
call holds the GIL.  Processes need no GIL but each loads the compiled code
from the disk cache once, and every chunk travels pickled.
``benchmarks/ensemble_pools.py`` measures both; :data:`DEFAULT_POOL` is what won.

Ctrl-C (or SIGTERM on the command line) ends an ensemble as it ends a
:func:`hamrkq.solve` run: the result comes back with the members of every
chunk finished, and the others marked ``INTERRUPTED``
(:meth:`Collector.finish`).  The chunks running are not waited for: a
chunk is one call of the compiled batch loop, which cannot be stopped part
way, and can take seconds; a thread finishes it in the background and its
members are dropped, a process is ended.
"""

from __future__ import annotations

import concurrent.futures as cf
import math
import multiprocessing
import os
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np

from hamrkq.ensemble.chunk import STATS, ChunkResult, run_chunk
from hamrkq.ensemble.request import Request
from hamrkq.ensemble.result import EnsembleSolution
from hamrkq.errors import InputError, OptionError
from hamrkq.result import Status

__all__ = [
    "DEFAULT_POOL",
    "INTERRUPTED_MESSAGE",
    "POOLS",
    "Collector",
    "chunk_bounds",
    "run_local",
    "usable_cores",
]

POOLS = ("threads", "processes")
#: The pool ``workers > 1`` uses unless told otherwise; chosen by measurement
#: (``benchmarks/ensemble_pools.py``, output in ``benchmarks/ensemble_pools.txt``).
DEFAULT_POOL = "threads"
#: Upper bound of the default chunk size: big enough to amortise a task's cost
#: (pickling, scheduling), small enough for a smooth progress bar and for a
#: lost Dask task to cost little.
MAX_CHUNK = 200
#: Default number of chunks per worker, for load balance between fast and slow members.
CHUNKS_PER_WORKER = 8
#: The message of a member an interrupted ensemble did not finish.
INTERRUPTED_MESSAGE = (
    "Not integrated: the ensemble was interrupted (KeyboardInterrupt) before this "
    "member's chunk finished."
)


def usable_cores() -> int:
    """Cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def chunk_bounds(size: int, workers: int, chunk_size: int | None) -> list[tuple[int, int]]:
    """``[(start, stop), ...]`` covering ``range(size)`` in order."""
    if chunk_size is None:
        chunk_size = max(1, min(MAX_CHUNK, math.ceil(size / (CHUNKS_PER_WORKER * workers))))
    return [(a, min(a + chunk_size, size)) for a in range(0, size, chunk_size)]


class Collector:
    """The ensemble's arrays, filled chunk by chunk in whatever order chunks finish.

    Every member must arrive exactly once: a chunk that overlaps members
    already collected (a task run twice) is refused, and :meth:`finish`
    refuses an ensemble with members missing.
    """

    def __init__(self, request: Request):
        m, dim, times = request.size, request.ham.dim, request.times
        self.request = request
        self.y = np.full((m, times.size, dim), np.nan)
        self.t_last = np.full(m, np.nan)
        self.status = np.zeros(m, dtype=np.int8)
        self.max_global_error = np.full(m, np.nan)
        self.energy0 = np.full(m, np.nan)
        self.energy_drift = np.full(m, np.nan)
        self.stats = np.zeros((m, len(STATS)), dtype=np.int64)
        self.messages: dict[int, str] = {}
        self.seen = np.zeros(m, dtype=bool)
        self.done = 0

    def add(self, chunk: ChunkResult) -> int:
        """Store a chunk's results; returns the number of members it held."""
        a = chunk.start - self.request.start
        b = a + chunk.size
        if self.seen[a:b].any():
            raise RuntimeError(f"members {a}:{b} were delivered twice")
        self.y[a:b] = chunk.y
        self.t_last[a:b] = chunk.t_last
        self.status[a:b] = chunk.status
        self.max_global_error[a:b] = chunk.max_global_error
        self.energy0[a:b] = chunk.energy0
        self.energy_drift[a:b] = chunk.energy_drift
        self.stats[a:b] = chunk.stats
        self.messages.update({a + i: text for i, text in chunk.messages.items()})
        # Last: a chunk half stored when Ctrl-C lands counts as not arrived.
        self.seen[a:b] = True
        self.done += chunk.size
        return chunk.size

    def finish(
        self, interrupted: bool = False, why: str = INTERRUPTED_MESSAGE
    ) -> EnsembleSolution:
        """The :class:`EnsembleSolution`.

        Parameters
        ----------
        interrupted : bool
            The ensemble was stopped (Ctrl-C, SIGTERM, its Dask cluster gone):
            the members that never arrived get status ``INTERRUPTED``, NaN
            states and the message ``why``.  Otherwise every member must
            have arrived.
        why : str
            The message of the members that never arrived.
        """
        missing = np.flatnonzero(~self.seen)
        if missing.size and not interrupted:
            raise RuntimeError(f"{missing.size} members never arrived (first: {missing[0]})")
        self.status[missing] = Status.INTERRUPTED.code
        self.y[missing] = self.t_last[missing] = np.nan
        self.max_global_error[missing] = self.energy0[missing] = np.nan
        self.energy_drift[missing] = np.nan
        self.stats[missing] = 0
        self.messages.update({int(i): why for i in missing})
        r = self.request
        failed = np.array(sorted(self.messages), dtype=np.int64)
        names = [s.name for s in r.ham.parameters]
        return EnsembleSolution(
            t=r.times,
            y=self.y,
            y0=r.y0,
            t_last=self.t_last,
            status=self.status,
            max_global_error=self.max_global_error,
            energy0=self.energy0,
            energy_drift=self.energy_drift,
            failed=failed,
            messages=tuple(self.messages[int(i)] for i in failed),
            names=r.ham.names,
            method=str(r.options.get("method", "auto")),
            t_span=r.t_span,
            parameters={name: r.params[:, j] for j, name in enumerate(names)},
            stats={name: self.stats[:, k] for k, name in enumerate(STATS)},
            options=r.record(),
        )


def run_local(
    request: Request,
    workers: int,
    pool: str,
    chunk_size: int | None,
    progress: Callable[[int], None],
) -> EnsembleSolution:
    """Run every chunk here (``workers == 1``) or in a pool of ``workers``."""
    if pool not in POOLS:
        raise OptionError(f"pool={pool!r} is not valid; valid: {', '.join(map(repr, POOLS))}")
    collector = Collector(request)
    bounds = chunk_bounds(request.size, workers, chunk_size)
    if workers == 1 or len(bounds) <= 1:
        try:
            for a, b in bounds:
                progress(collector.add(run_chunk(request.subset(a, b))))
        except KeyboardInterrupt:
            return collector.finish(interrupted=True)
        return collector.finish()
    if pool == "threads":
        executor: cf.Executor = cf.ThreadPoolExecutor(workers, thread_name_prefix="hamrkq")
    else:
        # spawn, not fork: the parent may hold threads (numba's, a GUI's) and
        # locks that a forked child would inherit in an unknown state.
        context = multiprocessing.get_context("spawn")
        executor = cf.ProcessPoolExecutor(workers, mp_context=context)
    try:
        for chunk in _bounded(executor, request, bounds, 2 * workers):
            progress(collector.add(chunk))
    except KeyboardInterrupt:
        # Not ``with executor``, whose exit waits for the chunks running: a
        # compiled batch of up to MAX_CHUNK members each (6.5 s of
        # Henon-Heiles after SIGTERM).
        _abandon(executor)
        return collector.finish(interrupted=True)
    except BaseException:
        _abandon(executor)
        raise
    executor.shutdown(wait=True)
    return collector.finish()


def _abandon(executor: cf.Executor) -> None:
    """Stop ``executor`` without waiting for its running chunks: the queued
    ones are cancelled, a thread finishes its chunk in the background (a
    compiled call cannot be stopped from outside), a worker process is
    ended (Python 3.14's ``terminate_workers``, else each process)."""
    executor.shutdown(wait=False, cancel_futures=True)
    if isinstance(executor, cf.ProcessPoolExecutor):
        terminate = getattr(executor, "terminate_workers", None)
        if terminate is not None:
            terminate()
            return
        for process in list((getattr(executor, "_processes", None) or {}).values()):
            process.terminate()


def _bounded(
    executor: cf.Executor, request: Request, bounds: list[tuple[int, int]], window: int
) -> Iterator[ChunkResult]:
    """Chunk results as they finish, with at most ``window`` chunks in flight
    (a million members never become a million pending tasks)."""
    todo = iter(bounds)
    pending: set[cf.Future] = set()
    while True:
        for a, b in todo:
            pending.add(executor.submit(run_chunk, request.subset(a, b)))
            if len(pending) >= window:
                break
        if not pending:
            return
        finished, pending = cf.wait(pending, return_when=cf.FIRST_COMPLETED)
        for future in finished:
            yield future.result()


def check_workers(workers: Any) -> int:
    """``workers`` as a positive int (None: every usable core)."""
    if workers is None:
        return usable_cores()
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise InputError(f"workers must be a positive integer or None, got {workers!r}")
    return workers
