"""Running an ensemble's chunks on a Dask cluster (the optional ``dask`` extra).

Each chunk is one task: the task carries the chunk's :class:`Request` (the
Hamiltonian as its SymPy declaration, never compiled code) and returns plain
arrays.  A worker compiles the system once, through hamrkq's disk cache
(shared with the other workers of a machine), on its first task.  When a worker
dies, Dask reruns its lost tasks elsewhere; the :class:`~hamrkq.ensemble.local.Collector`
refuses a member delivered twice and an ensemble with a member missing.
"""

from __future__ import annotations

import uuid
from collections.abc import Callable
from typing import Any

from hamrkq.ensemble.chunk import run_chunk
from hamrkq.ensemble.local import Collector, chunk_bounds
from hamrkq.ensemble.request import Request
from hamrkq.ensemble.result import EnsembleSolution
from hamrkq.errors import InputTypeError, OptionError

__all__ = ["run_dask"]


def _distributed():
    try:
        import distributed
    except ImportError:
        raise OptionError(
            "scheduler='dask' needs dask.distributed: pip install 'hamrkq[dask]'"
        ) from None
    return distributed


def run_dask(
    request: Request,
    client: Any,
    workers: int | None,
    chunk_size: int | None,
    progress: Callable[[int], None],
) -> EnsembleSolution:
    """Run the chunks as tasks on ``client`` (None: a LocalCluster of
    ``workers`` single-threaded processes, closed at the end)."""
    distributed = _distributed()
    if client is None:
        cluster = distributed.LocalCluster(
            n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=":0"
        )
        with cluster, distributed.Client(cluster) as own:
            return _run(request, own, chunk_size, progress)
    if not isinstance(client, distributed.Client):
        raise InputTypeError(f"client must be a dask.distributed.Client, got {client!r}")
    return _run(request, client, chunk_size, progress)


def _run(request: Request, client: Any, chunk_size: int | None, progress) -> EnsembleSolution:
    distributed = _distributed()
    threads = sum(client.nthreads().values()) or 1
    collector = Collector(request)
    bounds = chunk_bounds(request.size, threads, chunk_size)
    # pure=False: two chunks with equal inputs are still two tasks, and a
    # rerun after a worker's death is Dask's business, not a cache hit.
    token = uuid.uuid4().hex
    futures = [
        client.submit(run_chunk, request.subset(a, b), pure=False, key=f"hamrkq-{token}-{a}")
        for a, b in bounds
    ]
    try:
        for future in distributed.as_completed(futures):
            progress(collector.add(future.result()))
            future.release()
    except KeyboardInterrupt:
        # As on this machine (hamrkq.ensemble.local): the chunks finished,
        # the other members marked interrupted.
        return collector.finish(interrupted=True)
    except Exception as exc:
        if not _gone(client):
            raise
        # The client or its cluster closed under the run: its tasks were
        # cancelled.  The chunks that came back stand, as after Ctrl-C.
        why = (
            "not run: the Dask client or its cluster closed during the ensemble "
            f"({type(exc).__name__}: {exc})"
        )
        return collector.finish(interrupted=True, why=why)
    finally:
        if not _gone(client):  # a closed client cannot cancel (ClosedClientError)
            client.cancel(futures)
    return collector.finish()


def _gone(client: Any) -> bool:
    """Whether ``client`` or its scheduler has gone away."""
    if client.status in ("closing", "closed"):
        return True
    try:
        client.scheduler_info()  # served from the client's cache: cheap
    except Exception:  # any failure to reach it means gone
        return True
    return client.scheduler is None
