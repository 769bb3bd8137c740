"""hamrkq: Hamiltonian systems integrated with Prentice's RKQ algorithm.

Write a Hamiltonian as a SymPy expression (or load one from the catalogue);
hamrkq derives Hamilton's equations and the Jacobian symbolically, generates
fast numerical code, and integrates with explicit Runge-Kutta methods under
stepwise control of the *global* error (J.S.C. Prentice, arXiv:1111.6996).

The public names below are imported on first use (PEP 562), so that
``import hamrkq`` and the command line start at once: SymPy, SciPy and numba
load when a name that needs them is first touched.  A Ctrl-C while they load
therefore lands inside the command line's handler, not in a traceback.
"""

from __future__ import annotations

import importlib
import sys
import types
from typing import TYPE_CHECKING, Any

from . import errors
from ._version import __version__

if TYPE_CHECKING:  # what the names are, for type checkers and editors
    from hamrkq.analysis.chaos import lyapunov, megno
    from hamrkq.analysis.diagnostics import Diagnostics, diagnose
    from hamrkq.analysis.poincare import poincare
    from hamrkq.catalogue.problems import Problem, list_problems, load_problem
    from hamrkq.ensemble import EnsembleSolution, ensemble
    from hamrkq.result import Solution, Status
    from hamrkq.rkq.scipy_solver import RK34Q8
    from hamrkq.solve import solve
    from hamrkq.symbolic.expressions import parse_expression
    from hamrkq.symbolic.hamiltonian import Hamiltonian

#: Public name -> the module that defines it.
_HOMES = {
    "lyapunov": "hamrkq.analysis.chaos",
    "megno": "hamrkq.analysis.chaos",
    "Diagnostics": "hamrkq.analysis.diagnostics",
    "diagnose": "hamrkq.analysis.diagnostics",
    "poincare": "hamrkq.analysis.poincare",
    "Problem": "hamrkq.catalogue.problems",
    "list_problems": "hamrkq.catalogue.problems",
    "load_problem": "hamrkq.catalogue.problems",
    "EnsembleSolution": "hamrkq.ensemble",
    "ensemble": "hamrkq.ensemble",
    "Solution": "hamrkq.result",
    "Status": "hamrkq.result",
    "RK34Q8": "hamrkq.rkq.scipy_solver",
    "solve": "hamrkq.solve",
    "parse_expression": "hamrkq.symbolic.expressions",
    "Hamiltonian": "hamrkq.symbolic.hamiltonian",
}

__all__ = [
    "RK34Q8",
    "Diagnostics",
    "EnsembleSolution",
    "Hamiltonian",
    "Problem",
    "Solution",
    "Status",
    "__version__",
    "diagnose",
    "ensemble",
    "errors",
    "list_problems",
    "load_problem",
    "lyapunov",
    "megno",
    "parse_expression",
    "poincare",
    "solve",
]


def __getattr__(name: str) -> Any:
    home = _HOMES.get(name)
    if home is None:
        raise AttributeError(f"module 'hamrkq' has no attribute {name!r}")
    value = getattr(importlib.import_module(home), name)
    globals()[name] = value
    return value


#: This module's own imports, which are not hamrkq's names (kept out of ``dir``,
#: so that tab completion offers what the package offers).
_IMPORTS = frozenset({"Any", "TYPE_CHECKING", "annotations", "importlib", "sys", "types"})


def __dir__() -> list[str]:
    return sorted({*globals(), *_HOMES} - _IMPORTS)


class _Package(types.ModuleType):
    """The package's module type: the submodule ``hamrkq.solve`` never
    replaces the function ``hamrkq.solve``.

    Python binds a submodule as an attribute of its package when it is first
    imported; for ``hamrkq.solve`` that would hide the function of the same
    name (``from hamrkq.solve import solve`` still finds the module in
    ``sys.modules``).
    """

    def __setattr__(self, name: str, value: Any) -> None:
        if isinstance(value, types.ModuleType) and name in _HOMES:
            return
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package
