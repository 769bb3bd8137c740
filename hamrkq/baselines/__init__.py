"""SciPy's ``solve_ivp`` methods as baselines that return a :class:`~hamrkq.Solution`.

The names live here, the solvers in :mod:`hamrkq.baselines.scipy_ivp`: naming
a method (option checks, ``METHODS``) must not import ``scipy.integrate``,
which takes 0.3 s and only a SciPy run needs.
"""

from types import MappingProxyType

__all__ = ["PREFIX", "SCIPY_SOLVER_HOMES"]

#: Method names in :func:`hamrkq.solve` are ``PREFIX + name``.
PREFIX = "scipy:"
#: The SciPy solvers by name (``solve_ivp``'s names, plus hamrkq's RK34Q8),
#: each with the module that defines it.
SCIPY_SOLVER_HOMES = MappingProxyType(
    {
        "RK23": "scipy.integrate",
        "RK45": "scipy.integrate",
        "DOP853": "scipy.integrate",
        "Radau": "scipy.integrate",
        "BDF": "scipy.integrate",
        "LSODA": "scipy.integrate",
        "RK34Q8": "hamrkq.rkq.scipy_solver",
    }
)
