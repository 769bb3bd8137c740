"""The command line: ``hamrkq list|show|run|reproduce|compare``.

Thin by design: each subcommand parses its arguments, calls the library and
turns the outcome into an exit status (0 success, 1 the integration failed,
2 bad usage or bad input).  Subcommands other than ``list`` and ``show`` live
in modules of their own (``hamrkq/commands/``) that register themselves through
:data:`COMMAND_MODULES`.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

import sympy as sp

from hamrkq._version import __version__
from hamrkq.catalogue.problems import list_problems, load_problem
from hamrkq.errors import HamrkqError

__all__ = ["EXIT_BAD_INPUT", "EXIT_FAILED", "EXIT_OK", "main"]

EXIT_OK = 0
EXIT_FAILED = 1
EXIT_BAD_INPUT = 2

#: Modules providing further subcommands: each has ``register(subparsers)``
#: which adds its parser and sets ``func`` (args -> exit status).
COMMAND_MODULES: tuple[str, ...] = (
    "hamrkq.cli.run",
    "hamrkq.cli.reproduce",
    "hamrkq.cli.compare",
)


class _Parser(argparse.ArgumentParser):
    """argparse exits with status 2 on bad usage already; keep its message short."""

    def error(self, message: str):  # pragma: no cover - exercised through main
        self.print_usage(sys.stderr)
        self.exit(EXIT_BAD_INPUT, f"hamrkq: error: {message}\n")


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
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status.

    Parameters
    ----------
    argv : sequence of str, optional
        The arguments, without the program name (default: ``sys.argv[1:]``).
    """
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:
        return int(exc.code or 0)
    try:
        return int(args.func(args))
    except HamrkqError as exc:
        print(f"hamrkq: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("hamrkq: interrupted", file=sys.stderr)
        return EXIT_FAILED
    except OSError as exc:
        # Writing results failed (disk full, permissions changed mid-run).
        print(f"hamrkq: error: cannot write output: {exc}", file=sys.stderr)
        return EXIT_FAILED


def _cmd_list(args: argparse.Namespace) -> int:
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
    q0 = ", ".join(f"{v:.17g}" for v in problem.q0)
    p0 = ", ".join(f"{v:.17g}" for v in problem.p0)
    out += ["", f"initial: q0 = [{q0}], p0 = [{p0}]", f"t_span:  {list(problem.t_span)}"]
    if problem.exact_spec is not None:
        out.append("exact solution: available")
    print("\n".join(out))
    return EXIT_OK


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
