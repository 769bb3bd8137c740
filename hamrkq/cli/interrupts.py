"""Ctrl-C and SIGTERM while a command runs.

SIGTERM (sent by ``timeout``, batch schedulers, ``docker stop``) is handled
like Ctrl-C (:func:`sigterm_as_interrupt`); both are recorded, so that a
command says in its report what stopped it (:func:`signals_received`,
:func:`quick_report`), held back while it writes its results
(:func:`interrupts_held`), raised again for a command that keeps no partial
results (:func:`raise_if_interrupted`), and delivered again where a C
callback swallowed them (:func:`interrupts_in_callbacks_delivered`).
"""

from __future__ import annotations

import _thread
import contextlib
import gc
import signal
import sys
import threading
from collections.abc import Iterator

# The signals received while the current command runs, SIGINT (Ctrl-C)
# included: kept in hamrkq._interruption, whose messages of the runs they
# stop name them (see :func:`signals_received`).
from hamrkq._interruption import COMMAND_RUNNING, RECEIVED

__all__ = [
    "QUICK_REPORT",
    "Terminated",
    "drop_half_built",
    "interrupted",
    "interrupts_held",
    "interrupts_in_callbacks_delivered",
    "quick_report",
    "raise_if_interrupted",
    "signals_received",
    "sigterm_as_interrupt",
]


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised where the signal lands, so that every ``except
    KeyboardInterrupt`` (the step loop, atomic writes, the report) treats it
    like Ctrl-C."""


def signals_received() -> tuple[str, ...]:
    """The signals other than Ctrl-C's (``"SIGTERM"``) the current command has
    received so far: a command says in its report that it was stopped by
    one, not by Ctrl-C."""
    return tuple(name for name in RECEIVED if name != "SIGINT")


#: The note of a command stopped by SIGTERM before its report: the report is
#: the quick one.  A scheduler kills the process a grace period after
#: SIGTERM (``docker stop``: 10 s) and nobody presses Ctrl-C a second time to
#: cut a long report short: the reference integration of a 587 000-node run
#: took 6 s, the figures 1-3 s (matplotlib's import alone 0.6 s).
QUICK_REPORT = (
    "the report after SIGTERM is the quick one: no figures and no reference "
    "integration (the true error is not measured)"
)


def quick_report() -> bool:
    """Whether the current command was stopped by SIGTERM (not Ctrl-C), so
    that its report leaves out what takes long (:data:`QUICK_REPORT`)."""
    return bool(signals_received())


def interrupted() -> bool:
    """Whether Ctrl-C or SIGTERM has reached the current command."""
    return bool(RECEIVED)


#: While a command writes its results (:func:`interrupts_held`): the
#: interrupts received meanwhile, held back.
_HELD: list[BaseException] = []
_HOLDING: list[bool] = [False]


@contextlib.contextmanager
def interrupts_held() -> Iterator[list[BaseException]]:
    """Hold Ctrl-C and SIGTERM back while the block writes results; yields
    the list of those received, for the caller to act on after it.

    Every file is written atomically, so an interrupt landing in a write
    left no file at all: writing summary.json with a run's 10 000 events
    takes 0.6 s, solution.npz of 587 000 nodes 0.1 s.  Held back, the file
    is written whole, and the command stops right after (the quick report
    after SIGTERM, the rest of the report skipped after Ctrl-C).
    """
    _HELD.clear()
    _HOLDING[0] = True
    held: list[BaseException] = []
    try:
        yield held
    finally:
        _HOLDING[0] = False
        held += _HELD
        _HELD.clear()


def raise_if_interrupted() -> None:
    """Raise the interrupt the current command received again (Terminated
    for SIGTERM, KeyboardInterrupt for Ctrl-C), if any: for a command that
    keeps no partial results and would otherwise go on after the run it
    stopped (``hamrkq compare``'s sweep)."""
    if not RECEIVED:
        return
    if RECEIVED[-1] == "SIGINT":
        raise KeyboardInterrupt
    raise Terminated(f"signal {RECEIVED[-1]}")


def _raise_terminated(signum: int, frame: object) -> None:
    name = signal.Signals(signum).name
    RECEIVED.append(name)
    if _HOLDING[0]:
        _HELD.append(Terminated(f"signal {name}"))
        return
    raise Terminated(f"signal {name}")


def _raise_interrupt(signum: int, frame: object) -> None:
    # Python's own handler (signal.default_int_handler), recorded.
    RECEIVED.append("SIGINT")
    if _HOLDING[0]:
        _HELD.append(KeyboardInterrupt())
        return
    raise KeyboardInterrupt


@contextlib.contextmanager
def sigterm_as_interrupt() -> Iterator[None]:
    """Handle SIGTERM like SIGINT while a command runs, and record both
    (main thread only: Python delivers signals there, and elsewhere cannot
    install handlers).  A SIGINT that is ignored (a job started in the
    background by a shell) stays ignored."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    RECEIVED.clear()
    previous = signal.signal(signal.SIGTERM, _raise_terminated)
    previous_int = signal.getsignal(signal.SIGINT)
    if previous_int is signal.default_int_handler:
        signal.signal(signal.SIGINT, _raise_interrupt)
    COMMAND_RUNNING[0] = True
    try:
        yield
    finally:
        COMMAND_RUNNING[0] = False
        signal.signal(signal.SIGTERM, previous)
        if previous_int is signal.default_int_handler:
            signal.signal(signal.SIGINT, previous_int)


#: True while an interrupted command drops what the interruption left
#: half-built (:func:`drop_half_built`).
_DROPPING_HALF_BUILT = False


def drop_half_built(exc: BaseException) -> None:
    """Free the frames an interruption ``exc`` unwound, and what they held,
    with their finalizers' errors unshown: Ctrl-C landing in the constructor
    of llvmlite's PassBuilder left one without its handle, whose ``__del__``
    then printed "Exception ignored ... AttributeError" with a traceback
    after "hamrkq: interrupted" (tests/test_startup.py, now and then)."""
    global _DROPPING_HALF_BUILT
    _DROPPING_HALF_BUILT = True
    try:
        exc.__traceback__ = None
        gc.collect()
    finally:
        _DROPPING_HALF_BUILT = False


#: Seconds after which an interrupt swallowed by a C callback is delivered
#: again (:func:`interrupts_in_callbacks_delivered`): the callback has
#: returned by then.
_REDELIVER_AFTER = 0.02


@contextlib.contextmanager
def interrupts_in_callbacks_delivered() -> Iterator[None]:
    """Ctrl-C (or SIGTERM) that lands while a C library calls back into
    Python (llvmlite's object cache, while numba loads compiled code) cannot
    be raised there: Python prints it as "Exception ignored on calling ctypes
    callback function", with a traceback, and the command goes on.  It is
    delivered again to the main thread instead, where the command stops as
    for any interruption."""
    previous = sys.unraisablehook

    def hook(unraisable) -> None:
        exc = unraisable.exc_value
        if _DROPPING_HALF_BUILT and not isinstance(exc, KeyboardInterrupt):
            return  # a finalizer of what the interruption left half-built
        if not isinstance(exc, KeyboardInterrupt):
            previous(unraisable)
            return
        terminated = isinstance(exc, Terminated)
        if RECEIVED and RECEIVED[-1] == ("SIGTERM" if terminated else "SIGINT"):
            RECEIVED.pop()  # its handler records it again
        # From another thread, a moment later: raised here, in the hook, it
        # would be swallowed the same way.
        timer = threading.Timer(
            _REDELIVER_AFTER,
            _thread.interrupt_main,
            (signal.SIGTERM if terminated else signal.SIGINT,),
        )
        timer.daemon = True
        timer.start()

    sys.unraisablehook = hook
    try:
        yield
    finally:
        sys.unraisablehook = previous
