"""The command line: ``hamrkq list|show|run|reproduce|compare``.

Thin by design: each subcommand parses its arguments, calls the library and
turns the outcome into an exit status (0 success, 1 the integration failed or
was interrupted, 2 bad usage or bad input, 3 the results could not be
written).  SIGTERM (sent by ``timeout``, batch schedulers, ``docker stop``) is
handled like Ctrl-C: the run stops, its partial results are written and
marked partial, and the exit status is 1 (:mod:`hamrkq.cli.interrupts`).
Subcommands other than ``list`` and ``show`` live in modules of their own
(``hamrkq/cli/run.py``, ...) that register themselves through
:data:`COMMAND_MODULES`.
"""

from __future__ import annotations

import argparse
import atexit
import contextlib
import importlib
import os
import re
import sys
import threading
import warnings
from collections.abc import Iterator, Sequence
from typing import NoReturn

from hamrkq._version import __version__
from hamrkq.cli.interrupts import (
    Terminated,
    drop_half_built,
    interrupted,
    interrupts_in_callbacks_delivered,
    sigterm_as_interrupt,
)
from hamrkq.errors import HamrkqError

__all__ = [
    "EXIT_BAD_INPUT",
    "EXIT_BROKEN_PIPE",
    "EXIT_FAILED",
    "EXIT_OK",
    "EXIT_WRITE_FAILED",
    "entry_point",
    "main",
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
            # Some warnings name hamrkq themselves ("hamrkq: the cached file
            # ... is damaged"), for a library user who sees them among
            # others'; here the prefix below says it once.
            text = str(message).removeprefix("hamrkq: ")
            print(f"hamrkq: warning: {text}", file=sys.stderr)
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


#: What argparse reads as a negative value rather than an option: a minus,
#: then a digit or a point and a digit, or a function's name and "(".
NEGATIVE_VALUE = re.compile(r"^-(\.?\d|[A-Za-z_]\w*\()")


class _Parser(argparse.ArgumentParser):
    """argparse exits with status 2 on bad usage already; keep its message short."""

    #: The subcommands' parsers by name (on the top-level parser).
    commands: dict[str, argparse.ArgumentParser] | None = None

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        # A value that starts with a minus is an option to argparse unless it
        # looks like a plain negative number (-10, -.5): ``--t-end -1e1``,
        # ``--energy -1/2`` (Kepler's bound orbits) and ``--energy
        # -sqrt(2)/20`` were refused with "expected one argument".  No
        # option of hamrkq's starts with a minus and a digit, a point or a
        # function's name and parenthesis, so such a word is a value.
        self._negative_number_matcher = NEGATIVE_VALUE

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
    with sigterm_as_interrupt(), interrupts_in_callbacks_delivered(), _warnings_as_messages():
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
            drop_half_built(exc)
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
    if threading.active_count() > 1 and not interrupted():
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
        values = ", ".join(
            f"{s} = {_shortest(problem.parameters[s.name])}" for s in ham.parameters
        )
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
