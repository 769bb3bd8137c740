"""Progress on a terminal: a run's bar, and a notice for a long wait.

:func:`hamrkq.solve` (``progress=True``) and the ``run`` and ``reproduce``
commands report how much of the time span is done, and the current ``t``,
through a :class:`ProgressBar`: a `tqdm <https://tqdm.github.io>`_ bar on
stderr, drawn only when stderr is a terminal (pipes, files and CI logs stay
quiet).  :class:`WaitNotice` says so when something before the run (the
first compilation of a system) takes long.
"""

from __future__ import annotations

import logging
import os
import sys
import threading
import time
from collections.abc import Callable
from typing import TextIO

from tqdm import tqdm

__all__ = ["BAR_FORMAT", "ProgressBar", "WaitNotice", "say", "tqdm_size"]

#: The bar's line: label, bar, share of the time span done, the current t
#: (tqdm's postfix), time spent and time left.
BAR_FORMAT = "{desc}: [{bar}] {percentage:5.1f}%{postfix} [{elapsed}<{remaining}]"
#: Columns and lines assumed when the terminal reports a size of 0 x 0 (a bare
#: pseudo-terminal): tqdm would draw nothing there.
FALLBACK_SIZE = (100, 24)


def _is_terminal(stream: TextIO) -> bool:
    isatty = getattr(stream, "isatty", None)
    return bool(isatty and isatty())


def tqdm_size(stream: TextIO) -> dict[str, int]:
    """tqdm's ``ncols`` and ``nrows`` for ``stream`` where it cannot find them
    itself; empty when the terminal reports its size."""
    try:
        columns, lines = os.get_terminal_size(stream.fileno())
    except (AttributeError, OSError, ValueError):
        return {}
    if columns > 0 and lines > 0:
        return {}
    return {"ncols": FALLBACK_SIZE[0], "nrows": FALLBACK_SIZE[1]}


class ProgressBar:
    """``progress(fraction, t)`` for :func:`hamrkq.solve`: a bar on a terminal.

    Nothing is drawn before ``delay`` seconds have passed since the bar was
    made (short runs stay quiet) or when ``stream`` is not a terminal (pipes,
    files, CI logs).  The tqdm bar itself starts at the first report, so its
    rate and time left count from there, not from a compilation before it.

    Parameters
    ----------
    label : str
        Shown before the bar.
    stream : file, optional
        Default ``sys.stderr``.
    delay : float
        Seconds before the bar first appears.
    enabled : bool, optional
        Force the bar on or off; default: whether ``stream`` is a terminal.
    """

    def __init__(
        self,
        label: str,
        *,
        stream: TextIO | None = None,
        delay: float = 1.0,
        enabled: bool | None = None,
    ):
        self.label = label
        self.stream = sys.stderr if stream is None else stream
        self.enabled = _is_terminal(self.stream) if enabled is None else enabled
        self.delay = delay
        self.start = time.monotonic()
        self._bar: tqdm | None = None

    def __call__(self, fraction: float, t: float) -> None:
        if not self.enabled:
            return
        fraction = min(max(fraction, 0.0), 1.0)
        postfix = f"t={t:.6g}"
        if self._bar is None:
            self._bar = tqdm(
                total=1.0,
                initial=fraction,
                desc=self.label,
                postfix=postfix,
                file=self.stream,
                delay=max(0.0, self.delay - (time.monotonic() - self.start)),
                bar_format=BAR_FORMAT,
                ascii=".#",
                leave=True,
                **tqdm_size(self.stream),
            )
            return
        self._bar.set_postfix_str(postfix, refresh=False)
        self._bar.update(fraction - self._bar.n)

    def close(self) -> None:
        """End the bar's line (if one was drawn)."""
        if self._bar is not None:
            self._bar.close()
            self._bar = None

    def __enter__(self) -> ProgressBar:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def say(text: str, stream: TextIO | None = None, enabled: bool | None = None) -> None:
    """One line for the user: on the ``hamrkq`` logger, and on ``stream``
    (stderr) when it is a terminal (or ``enabled``)."""
    logging.getLogger("hamrkq").info(text)
    stream = sys.stderr if stream is None else stream
    if _is_terminal(stream) if enabled is None else enabled:
        print(f"hamrkq: {text}", file=stream, flush=True)


class WaitNotice:
    """Say so when a wait is long: ``begin()`` once it has lasted ``after``
    seconds, then how long it took.  Lines go to ``stream`` (stderr) when it
    is a terminal (or ``enabled``), and always to the ``hamrkq`` logger.

    Parameters
    ----------
    begin : callable
        The first line (called only if the notice is shown).
    done : str
        The second line's start, followed by `` in <seconds> s``.
    after : float
        Seconds of silence first: a short wait says nothing.
    stream, enabled
        As for :class:`ProgressBar`.
    """

    def __init__(
        self,
        begin: Callable[[], str],
        done: str,
        after: float,
        *,
        stream: TextIO | None = None,
        enabled: bool | None = None,
    ):
        self.begin, self.done = begin, done
        self.stream = sys.stderr if stream is None else stream
        self.enabled = _is_terminal(self.stream) if enabled is None else enabled
        self.said = False
        self.started = time.perf_counter()
        self.timer = threading.Timer(after, self._start)
        self.timer.daemon = True

    def _say(self, text: str) -> None:
        say(text, self.stream, self.enabled)

    def _start(self) -> None:
        self.said = True
        self._say(self.begin())

    def __enter__(self) -> WaitNotice:
        self.timer.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.timer.cancel()
        self.timer.join()
        if self.said:
            self._say(f"{self.done} in {time.perf_counter() - self.started:.1f} s")
