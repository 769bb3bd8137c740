"""`ensemble`: many members of one Hamiltonian system, integrated in parallel."""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Mapping
from typing import Any

from hamrkq.ensemble.local import DEFAULT_POOL, POOLS, check_workers, run_local
from hamrkq.ensemble.request import build_request
from hamrkq.ensemble.result import EnsembleSolution
from hamrkq.errors import InputTypeError, OptionError

__all__ = ["SCHEDULERS", "ensemble"]

#: Where the chunks run: ``"auto"`` (this machine, the pool :data:`DEFAULT_POOL`),
#: ``"serial"``, ``"threads"``, ``"processes"`` or ``"dask"``.
SCHEDULERS = ("auto", "serial", *POOLS, "dask")


def ensemble(  # noqa: PLR0913 - the contract's keywords (PRODUCT.md) plus where and how to run
    problem_or_hamiltonian: Any,
    q0: Any = None,
    p0: Any = None,
    t_span: Any = None,
    *,
    parameters: Mapping[Any, Any] | None = None,
    t_eval: Any = None,
    workers: int | None = None,
    client: Any = None,
    scheduler: str = "auto",
    chunk_size: int | None = None,
    progress: bool | Callable[[int, int], None] | None = None,
    **solve_options: Any,
) -> EnsembleSolution:
    """Integrate many initial conditions and/or parameter values of one system.

    Every member is integrated exactly as :func:`hamrkq.solve` integrates it
    alone, with the same options (so with the same numbers, bit for bit); a
    member that fails (step limit, non-finite state, ...) is marked in
    ``status`` and never stops the others.

    Parameters
    ----------
    problem_or_hamiltonian : Problem or Hamiltonian
        The system.  A :class:`~hamrkq.catalogue.problems.Problem` supplies
        defaults: its initial values (for each member's parameters), its
        ``t_span`` and its ``[integration]`` settings.
    q0, p0 : array (n,) or (M, n), or mapping of names to numbers or (M,) arrays
        Initial coordinates and momenta, one row per member; a single row, a
        scalar or a name left out is shared by every member (with a Problem,
        a name left out takes the problem's value).
    t_span : (t0, t_end)
        The interval, common to all members.
    parameters : mapping of names (or symbols) to numbers or (M,) arrays, optional
        Parameter values by name, one per member or one for all.
    t_eval : array, optional
        Times at which every member's state is kept (within ``t_span``,
        strictly monotonic).  Without it only each member's last state is kept.
    workers : int, optional
        How many cores (or Dask worker processes, for a LocalCluster) to use;
        default: every core this process may use.  ``workers=1`` runs here.
    client : dask.distributed.Client, optional
        Run the chunks on this Dask cluster (implies ``scheduler="dask"``).
    scheduler : {"auto", "serial", "threads", "processes", "dask"}
        ``"auto"``: this machine, on a pool of ``workers`` threads when
        ``workers > 1`` (measured no slower than processes, which also pay
        seconds to start and load the compiled code; see ``docs/ensembles.md``).
        ``"processes"`` starts them with ``spawn``: a script must guard its
        entry point with ``if __name__ == "__main__":``.
        ``"dask"`` without ``client`` starts a ``LocalCluster`` of ``workers``
        processes and closes it at the end (needs the ``dask`` extra).
    chunk_size : int, optional
        Members per task; default: about eight tasks per worker, at most 200
        members each.
    progress : bool or callable, optional
        None or True: a progress bar over members (tqdm) on a terminal, none
        otherwise; False: none; a callable is called as ``progress(done, total)``
        after each chunk.
    **solve_options
        Any keyword option of :func:`hamrkq.solve` (``method``, ``atol``,
        ``rtol``, ``max_steps``, ...), applied to every member.  ``keep_every``
        and ``progress`` are the ensemble's own business and are refused, as
        are ``dense_output`` and events that are not terminal (their results
        would be thrown away: the ensemble keeps states, not event times); a
        terminal event ends its member.

    Returns
    -------
    EnsembleSolution
        ``t`` (the kept times), ``y`` (member, time, state), per-member
        ``status``, ``t_last``, ``max_global_error``, ``energy_drift``,
        ``stats`` and the messages of the members that failed.

    Raises
    ------
    InputError, InputTypeError, OptionError
        Bad input, found before any member runs, with the parameter (and the
        member) named.

    Examples
    --------
    >>> import numpy as np, hamrkq
    >>> pendulum = hamrkq.load_problem("pendulum")
    >>> q0 = np.linspace(-3, 3, 7)[:, None]
    >>> ens = hamrkq.ensemble(pendulum, q0=q0, p0=[0.0], t_span=(0, 10), workers=1)
    >>> ens.y.shape
    (7, 1, 2)
    """
    if scheduler not in SCHEDULERS:
        raise OptionError(
            f"scheduler={scheduler!r} is not valid; valid: {', '.join(map(repr, SCHEDULERS))}"
        )
    if client is not None and scheduler not in ("auto", "dask"):
        raise OptionError(
            f"client= runs on Dask; it cannot be combined with scheduler={scheduler!r}"
        )
    if chunk_size is not None and (
        isinstance(chunk_size, bool) or not isinstance(chunk_size, int) or chunk_size < 1
    ):
        raise OptionError(f"chunk_size must be a positive integer, got {chunk_size!r}")
    n_workers = check_workers(workers)
    request = build_request(
        problem_or_hamiltonian, q0, p0, t_span, parameters, t_eval, dict(solve_options)
    )
    with _Progress(progress, request.size) as advance:
        if client is not None or scheduler == "dask":
            from hamrkq.ensemble.distributed import run_dask

            return run_dask(request, client, workers, chunk_size, advance)
        if scheduler == "serial":
            n_workers = 1
        pool = DEFAULT_POOL if scheduler in ("auto", "serial") else scheduler
        return run_local(request, n_workers, pool, chunk_size, advance)


class _Progress:
    """``advance(members)`` for the runners: a tqdm bar, a callable, or nothing."""

    def __init__(self, progress: Any, total: int):
        if not (progress is None or isinstance(progress, bool) or callable(progress)):
            raise InputTypeError(f"progress must be a bool or a callable, got {progress!r}")
        self.progress, self.total, self.done = progress, total, 0
        self.bar = None
        if progress is None or progress is True:
            from tqdm.auto import tqdm

            from hamrkq._progress import tqdm_size

            # disable=None: drawn only when stderr is a terminal (one of
            # 0 x 0, a bare pseudo-terminal, too: tqdm drew nothing there).
            self.bar = tqdm(
                total=total, unit="member", disable=None, delay=1.0, file=sys.stderr,
                **tqdm_size(sys.stderr),
            )  # fmt: skip
        self.started = time.monotonic()

    def __enter__(self) -> Callable[[int], None]:
        return self.advance

    def advance(self, members: int) -> None:
        self.done += members
        if self.bar is not None:
            self.bar.update(members)
        elif callable(self.progress) and not isinstance(self.progress, bool):
            self.progress(self.done, self.total)

    def __exit__(self, *exc: object) -> None:
        if self.bar is not None:
            self.bar.close()
