"""What interrupted a run, for its message.

The command line records the signals a command receives here
(:mod:`hamrkq.cli.interrupts`, which raises SIGTERM as a
``KeyboardInterrupt``), so that the message of a run it stopped names the
signal; a library caller's Ctrl-C is a ``KeyboardInterrupt``.
"""

from __future__ import annotations

__all__ = ["RECEIVED", "cause", "interrupted_near"]

#: Names of the signals the current command has received, in order, SIGINT
#: (Ctrl-C) included; kept by :mod:`hamrkq.cli.interrupts`, empty outside a
#: command.
RECEIVED: list[str] = []


def cause() -> str:
    """What interrupted the run: the last signal the command line recorded
    (``"SIGTERM"``), or ``"KeyboardInterrupt"`` for Ctrl-C and for an
    interrupt outside a command."""
    last = RECEIVED[-1] if RECEIVED else "SIGINT"
    return "KeyboardInterrupt" if last == "SIGINT" else last


def interrupted_near(t: float) -> str:
    """The sentence an interrupted run's message starts with."""
    return f"Interrupted ({cause()}) near t = {float(t)!r}."
