"""The command line: ``hamrkq list|show|run|reproduce|compare``.

Thin by design: each subcommand parses its arguments, calls the library and
turns the outcome into an exit status (0 success, 1 the integration failed or
was interrupted, 2 bad usage or bad input, 3 the results could not be
written).  SIGTERM (sent by ``timeout``, batch schedulers, ``docker stop``) is
handled like Ctrl-C: the run stops, its partial results are written and
marked partial, and the exit status is 1.  Subcommands other than ``list`` and ``show`` live
in modules of their own (``hamrkq/commands/``) that register themselves through
:data:`COMMAND_MODULES`.
"""

from __future__ import annotations

import _thread
import argparse
import atexit
import contextlib
import gc
import importlib
import os
import signal
import sys
import threading
import warnings
from collections.abc import Iterator, Sequence
from typing import NoReturn

from hamrkq._version import __version__
from hamrkq.errors import HamrkqError

__all__ = [
    "EXIT_BAD_INPUT",
    "EXIT_BROKEN_PIPE",
    "EXIT_FAILED",
    "EXIT_OK",
    "EXIT_WRITE_FAILED",
    "QUICK_REPORT",
    "Terminated",
    "entry_point",
    "interrupted",
    "interrupts_held",
    "main",
    "quick_report",
    "raise_if_interrupted",
    "signals_received",
]

EXIT_OK = 0
EXIT_FAILED = 1
EXIT_BAD_INPUT = 2
#: The results could not be written (disk full, permissions changed mid-run):
#: not "the integration failed", which is 1.
EXIT_WRITE_FAILED = 3
#: Standard output was closed by its reader (``hamrkq run ... | head``): the
#: shell's status for a process ended by SIGPIPE (128 + 13).
EXIT_BROKEN_PIPE = 141


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised where the signal lands, so that every ``except
    KeyboardInterrupt`` (the step loop, atomic writes, the report) treats it
    like Ctrl-C."""


#: Names of the signals received while the current command ran, SIGINT
#: (Ctrl-C) included (see :func:`signals_received`).
_RECEIVED: list[str] = []


def signals_received() -> tuple[str, ...]:
    """The signals other than Ctrl-C's (``"SIGTERM"``) the current command has
    received so far: a command says in its report that it was stopped by
    one, not by Ctrl-C."""
    return tuple(name for name in _RECEIVED if name != "SIGINT")


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
    return bool(_RECEIVED)


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
    if not _RECEIVED:
        return
    if _RECEIVED[-1] == "SIGINT":
        raise KeyboardInterrupt
    raise Terminated(f"signal {_RECEIVED[-1]}")


def _raise_terminated(signum: int, frame: object) -> None:
    name = signal.Signals(signum).name
    _RECEIVED.append(name)
    if _HOLDING[0]:
        _HELD.append(Terminated(f"signal {name}"))
        return
    raise Terminated(f"signal {name}")


def _raise_interrupt(signum: int, frame: object) -> None:
    # Python's own handler (signal.default_int_handler), recorded.
    _RECEIVED.append("SIGINT")
    if _HOLDING[0]:
        _HELD.append(KeyboardInterrupt())
        return
    raise KeyboardInterrupt


@contextlib.contextmanager
def _sigterm_as_interrupt() -> Iterator[None]:
    """Handle SIGTERM like SIGINT while a command runs, and record both
    (main thread only: Python delivers signals there, and elsewhere cannot
    install handlers).  A SIGINT that is ignored (a job started in the
    background by a shell) stays ignored."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    _RECEIVED.clear()
    previous = signal.signal(signal.SIGTERM, _raise_terminated)
    previous_int = signal.getsignal(signal.SIGINT)
    if previous_int is signal.default_int_handler:
        signal.signal(signal.SIGINT, _raise_interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)
        if previous_int is signal.default_int_handler:
            signal.signal(signal.SIGINT, previous_int)


#: True while an interrupted command drops what the interruption left
#: half-built (:func:`_drop_half_built`).
_DROPPING_HALF_BUILT = False


def _drop_half_built(exc: BaseException) -> None:
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
#: again (:func:`_interrupts_in_callbacks_delivered`): the callback has
#: returned by then.
_REDELIVER_AFTER = 0.02


@contextlib.contextmanager
def _interrupts_in_callbacks_delivered() -> Iterator[None]:
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
        if _RECEIVED and _RECEIVED[-1] == ("SIGTERM" if terminated else "SIGINT"):
            _RECEIVED.pop()  # its handler records it again
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


@contextlib.contextmanager
def _warnings_as_messages() -> Iterator[None]:
    """hamrkq's own warnings printed as ``hamrkq: warning: ...`` on stderr,
    like its errors (Python's default names the console script's file and
    line, which mean nothing to a user of the command line); other
    warnings as Python shows them."""
    from hamrkq.errors import HamrkqWarning

    previous = warnings.showwarning

    def show(message, category, filename, lineno, file=None, line=None):
        if issubclass(category, HamrkqWarning):
            print(f"hamrkq: warning: {message}", file=sys.stderr)
            return
        previous(message, category, filename, lineno, file, line)

    warnings.showwarning = show
    try:
        yield
    finally:
        warnings.showwarning = previous


#: Modules providing further subcommands: each has ``register(subparsers)``
#: which adds its parser and sets ``func`` (args -> exit status).
COMMAND_MODULES: tuple[str, ...] = (
    "hamrkq.cli.run",
    "hamrkq.cli.reproduce",
    "hamrkq.cli.compare",
    "hamrkq.cli.ensemble",
    "hamrkq.cli.poincare",
    "hamrkq.cli.compile",
)


class _Parser(argparse.ArgumentParser):
    """argparse exits with status 2 on bad usage already; keep its message short."""

    #: The subcommands' parsers by name (on the top-level parser).
    commands: dict[str, argparse.ArgumentParser] | None = None

    def error(self, message: str):  # pragma: no cover - exercised through main
        self.print_usage(sys.stderr)
        self.exit(EXIT_BAD_INPUT, f"hamrkq: error: {message}\n")

    def parse_args(self, args=None, namespace=None):  # type: ignore[override]
        """As argparse's, but an unknown option is reported with the usage of
        the subcommand it was given to (argparse's own reports it with the
        top-level usage, ``hamrkq [-h] [--version] COMMAND ...``)."""
        parsed, extra = self.parse_known_args(args, namespace)
        if extra:
            command = getattr(parsed, "command", None)
            parser = (self.commands or {}).get(command, self)
            parser.error(f"unrecognized arguments: {' '.join(extra)}")
        return parsed


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every available subcommand."""
    parser = _Parser(
        prog="hamrkq",
        description="Hamiltonian systems with stepwise global-error control (RKQ).",
    )
    parser.add_argument("--version", action="version", version=f"hamrkq {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True

    listing = sub.add_parser("list", help="list the problem catalogue")
    listing.set_defaults(func=_cmd_list)

    show = sub.add_parser("show", help="show H, Hamilton's equations, the Jacobian, invariants")
    show.add_argument("problem", metavar="NAME|FILE", help="catalogue name or .toml file")
    show.add_argument("--latex", action="store_true", help="print LaTeX instead of text")
    show.set_defaults(func=_cmd_show)

    for name in COMMAND_MODULES:
        try:
            module = importlib.import_module(name)
        except ModuleNotFoundError as exc:
            if exc.name != name:
                raise
            continue  # that subcommand is not part of this build
        module.register(sub)
    parser.commands = dict(sub.choices)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status.

    Parameters
    ----------
    argv : sequence of str, optional
        The arguments, without the program name (default: ``sys.argv[1:]``).
    """
    with _sigterm_as_interrupt(), _interrupts_in_callbacks_delivered(), _warnings_as_messages():
        try:
            parser = build_parser()
            try:
                args = parser.parse_args(argv)
            except SystemExit as exc:
                return int(exc.code or 0)
            return int(args.func(args))
        except HamrkqError as exc:
            print(f"hamrkq: error: {exc}", file=sys.stderr)
            return EXIT_BAD_INPUT
        except KeyboardInterrupt as exc:
            # Before the step loop started (deriving, compiling) or in a
            # command without partial results: nothing to keep.
            what = "terminated (SIGTERM)" if isinstance(exc, Terminated) else "interrupted"
            print(f"hamrkq: {what}", file=sys.stderr)
            _drop_half_built(exc)
            return EXIT_FAILED
        except BrokenPipeError:
            # The reader of standard output went away (a pipe into head): not
            # a failure to write the results, which are written before the
            # table.  Quietly, as other command-line tools, and with stdout
            # pointed at /dev/null so that the interpreter's last flush does
            # not complain.
            _silence_stdout()
            return EXIT_BROKEN_PIPE
        except OSError as exc:
            # Writing results failed (disk full, permissions changed mid-run).
            print(f"hamrkq: error: cannot write output: {exc}", file=sys.stderr)
            return EXIT_WRITE_FAILED
        finally:
            _release_outputs()


def _silence_stdout() -> None:
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):  # no file descriptor (a test's captured stream)
        pass


def entry_point() -> NoReturn:
    """The ``hamrkq`` program (console script and ``python -m hamrkq``):
    :func:`main`, then a quick exit.

    A normal interpreter shutdown tears down every module and frees numba's
    compiled code object by object: about 0.6 s after a ``hamrkq run
    prentice2011 --no-plots`` whose work took 1.6 s.  Nothing needs that
    teardown once :func:`main` has returned (it has closed every output),
    so the streams are flushed, the ``atexit`` handlers run (logging,
    ``weakref.finalize``, multiprocessing) and the process ends.  If another
    thread is still running, the shutdown is the normal one, which waits for
    it, unless the command was interrupted (Ctrl-C or SIGTERM): its results
    are written, and the threads' work is what was asked to stop (an
    ensemble's chunks in compiled code, which cannot be stopped from
    outside: ``hamrkq ensemble`` took 6.5 s to exit after SIGTERM).  Tests
    and other callers in a process of their own use :func:`main`.
    """
    status = main()
    if threading.active_count() > 1 and not _RECEIVED:
        sys.exit(status)
    atexit._run_exitfuncs()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass  # a closed pipe or stream: nothing left to tell anyone
    os._exit(status)


def _release_outputs() -> None:
    """Release every ``--out`` claimed, however the command ended (nothing
    was claimed if the report module was never imported)."""
    report = sys.modules.get("hamrkq.io.report")
    if report is not None:
        report.close_all()


def _cmd_list(args: argparse.Namespace) -> int:
    from hamrkq.catalogue.problems import list_problems, load_problem

    rows = []
    for name in list_problems():
        try:
            problem = load_problem(name)
            rows.append((name, str(problem.hamiltonian.n), problem.title))
        except HamrkqError as exc:
            rows.append((name, "?", f"(cannot load: {exc})"))
    width = max((len(r[0]) for r in rows), default=4)
    print(f"{'name':<{width}}  dof  title")
    for name, dof, title in rows:
        print(f"{name:<{width}}  {dof:>3}  {title}")
    return EXIT_OK


def _cmd_show(args: argparse.Namespace) -> int:
    import sympy as sp

    from hamrkq.catalogue.problems import load_problem

    problem = load_problem(args.problem)
    ham = problem.hamiltonian
    fmt = sp.latex if args.latex else sp.sstr
    out = [f"{problem.name}: {problem.title}", ""]
    out.append(f"coordinates: {', '.join(map(str, ham.q))}")
    out.append(f"momenta:     {', '.join(map(str, ham.p))}")
    if ham.parameters:
        values = ", ".join(f"{s} = {problem.parameters[s.name]:g}" for s in ham.parameters)
        out.append(f"parameters:  {values}")
    out += ["", "H =", f"  {fmt(ham.H)}", "", "Hamilton's equations:"]
    for y, f in zip(ham.state, ham.rhs, strict=True):
        lhs = rf"\frac{{d{sp.latex(y)}}}{{dt}}" if args.latex else f"d{y}/dt"
        out.append(f"  {lhs} = {fmt(f)}")
    out += ["", "Jacobian d(rhs)/d(q, p):"]
    if args.latex:
        out.append(f"  {sp.latex(ham.jacobian)}")
    else:
        out += [f"  {fmt(list(row))}" for row in ham.jacobian.tolist()]
    out += ["", "Invariants (checked symbolically: {F, H} + dF/dt == 0):"]
    invariants = {"H": ham.H, **problem.invariants}
    for name, expr in invariants.items():
        verdict = "conserved" if ham.is_first_integral(expr) else "NOT proved conserved"
        out.append(f"  {name} = {fmt(expr)}   [{verdict}]")
    q0 = ", ".join(map(_shortest, problem.q0))
    p0 = ", ".join(map(_shortest, problem.p0))
    out += ["", f"initial: q0 = [{q0}], p0 = [{p0}]", f"t_span:  {list(problem.t_span)}"]
    if problem.exact_spec is not None:
        out.append("exact solution: available")
    print("\n".join(out))
    return EXIT_OK


def _shortest(value: float) -> str:
    """The shortest text that reads back as the same double (``repr``: 0.4,
    where ``%.17g`` gave 0.40000000000000002), an integral value without
    its ``.0``."""
    text = repr(float(value))
    return text.removesuffix(".0")


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
