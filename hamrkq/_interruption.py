"""What interrupted a run, for its message.

The command line records the signals a command receives here
(:mod:`hamrkq.cli.interrupts`, which raises SIGTERM as a
``KeyboardInterrupt``), so that the message of a run it stopped names the
signal; a library caller's Ctrl-C is a ``KeyboardInterrupt``.
"""

from __future__ import annotations

__all__ = ["COMMAND_RUNNING", "RECEIVED", "cause", "interrupted_near"]

#: Names of the signals the last command received, in order, SIGINT (Ctrl-C)
#: included; kept by :mod:`hamrkq.cli.interrupts`.
RECEIVED: list[str] = []

#: ``[True]`` while a command runs with its signal handlers
#: (:func:`hamrkq.cli.interrupts.sigterm_as_interrupt`).
COMMAND_RUNNING: list[bool] = [False]


def cause() -> str:
    """What interrupted the run: the last signal the running command
    recorded (``"SIGTERM"``), or ``"KeyboardInterrupt"`` for Ctrl-C and for
    an interrupt outside a command (a library call after a command in the
    same process is not told the command's signal)."""
    last = RECEIVED[-1] if RECEIVED and COMMAND_RUNNING[0] else "SIGINT"
    return "KeyboardInterrupt" if last == "SIGINT" else last


def interrupted_near(t: float) -> str:
    """The sentence an interrupted run's message starts with."""
    return f"Interrupted ({cause()}) near t = {float(t)!r}."
