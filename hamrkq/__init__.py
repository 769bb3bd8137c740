"""hamrkq: Hamiltonian systems integrated with Prentice's RKQ algorithm.

Write a Hamiltonian as a SymPy expression (or load one from the catalogue);
hamrkq derives Hamilton's equations and the Jacobian symbolically, generates
fast numerical code, and integrates with explicit Runge-Kutta methods under
stepwise control of the *global* error (J.S.C. Prentice, arXiv:1111.6996).
"""

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

from . import errors
from ._version import __version__

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
