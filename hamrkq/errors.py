"""The exception and warning hierarchy of hamrkq.

Every error hamrkq raises derives from :class:`HamrkqError`.  Errors caused by
bad input are also :class:`ValueError` or :class:`TypeError` subclasses, so
code written against NumPy/SciPy habits (``except ValueError``) keeps working.

Numerical failures during a run are *not* exceptions: :func:`hamrkq.solve`
returns the nodes computed so far with ``success=False`` and a status (see
:class:`hamrkq.result.Status`).  The one exception is :class:`IntegrationError`,
raised only where a caller asked for it explicitly.
"""

from __future__ import annotations

import os
import sys
import warnings
from collections.abc import Iterable
from pathlib import Path

__all__ = [
    "CodegenError",
    "ExpressionError",
    "HamiltonianError",
    "HamrkqError",
    "HamrkqWarning",
    "InputError",
    "InputTypeError",
    "IntegrationError",
    "OptionError",
    "ProblemFileError",
    "ProblemNotFoundError",
    "ResultFileError",
    "SolutionFileError",
    "UndeclaredSymbolError",
    "warn",
]


class HamrkqError(Exception):
    """Base class of every error raised by hamrkq."""


class InputError(HamrkqError, ValueError):
    """A value passed to a public function is not acceptable.

    The message names the parameter and the offending value.
    """


class InputTypeError(HamrkqError, TypeError):
    """A value passed to a public function has the wrong type."""


class OptionError(InputError):
    """An unknown option name or option value (method, keyword argument, ...)."""


class HamiltonianError(InputError):
    """A Hamiltonian failed validation.

    Parameters
    ----------
    problems : iterable of str
        Every problem found; all are reported in one message.
    """

    def __init__(self, problems: Iterable[str]):
        self.problems = tuple(problems)
        if len(self.problems) == 1:
            message = f"invalid Hamiltonian: {self.problems[0]}"
        else:
            lines = "\n".join(f"  - {item}" for item in self.problems)
            message = f"invalid Hamiltonian ({len(self.problems)} problems):\n{lines}"
        super().__init__(message)


class UndeclaredSymbolError(HamiltonianError):
    """An expression uses symbols that are neither coordinates, momenta,
    parameters nor the time ``t``."""

    def __init__(self, symbols: Iterable[str], problems: Iterable[str] = ()):
        self.symbols = tuple(sorted(symbols))
        own = f"undeclared symbols: {', '.join(self.symbols)}"
        super().__init__([own, *problems])


class ProblemFileError(InputError):
    """A problem file (TOML) is malformed.

    Parameters
    ----------
    message : str
        What is wrong.
    path : str or Path, optional
        The file.
    key : str, optional
        The dotted TOML key at fault, for example ``"initial.q"``.
    line : int, optional
        The line number in the file, when known.
    """

    def __init__(
        self,
        message: str,
        *,
        path: str | Path | None = None,
        key: str | None = None,
        line: int | None = None,
    ):
        self.path = None if path is None else str(path)
        self.key = key
        self.line = line
        self.detail = message
        where = []
        if self.path is not None:
            where.append(self.path if line is None else f"{self.path}:{line}")
        if key is not None:
            where.append(f"key '{key}'")
        prefix = ", ".join(where)
        super().__init__(f"{prefix}: {message}" if prefix else message)


class ExpressionError(ProblemFileError):
    """An expression string was rejected by the restricted parser.

    ``piece`` is the offending part of the text.
    """

    def __init__(
        self,
        message: str,
        *,
        piece: str | None = None,
        path: str | Path | None = None,
        key: str | None = None,
        line: int | None = None,
    ):
        self.piece = piece
        if piece is not None:
            message = f"{message}: {piece!r}"
        super().__init__(message, path=path, key=key, line=line)


class ProblemNotFoundError(InputError, LookupError):
    """Neither a catalogue entry nor a file of that name exists."""


class SolutionFileError(InputError):
    """A file given to :meth:`hamrkq.Solution.load` is not a solution file.

    Parameters
    ----------
    path : str or Path
        The file.
    message : str
        What is wrong with it.
    """

    def __init__(self, path: str | Path, message: str):
        self.path = str(path)
        self.detail = message
        super().__init__(f"{self.path}: {message}")


class ResultFileError(InputError):
    """A result file (an ensemble's ``.npz``, say) is missing, foreign or damaged."""


class IntegrationError(HamrkqError, RuntimeError):
    """An integration failed and the caller asked for an exception."""


class HamrkqWarning(UserWarning):
    """Warnings issued by hamrkq (tolerance clamped, backend fallback, ...)."""


#: Directories whose frames a warning never points into: hamrkq itself and
#: SciPy's integrators (``solve_ivp(..., method=RK34Q8)`` is the user's call).
_INTERNAL = (
    os.path.dirname(os.path.abspath(__file__)) + os.sep,
    os.path.join("scipy", "integrate", ""),
)


class CodegenError(HamrkqError, ValueError):
    """An expression cannot be turned into scalar code (an unsupported
    function, an infinity or NaN, or a symbol that is not part of the system)."""


def warn(message: str, category: type[Warning] = HamrkqWarning) -> None:
    """Issue a warning that points at the first caller outside hamrkq.

    A fixed ``stacklevel`` is right for one call path only (``solve`` calls
    the backend chooser, which warns; ``solve_ivp`` constructs ``RK34Q8``,
    which warns): this walks the stack instead, past every frame in hamrkq's
    package and in ``scipy.integrate``, so the warning names the user's line.

    Parameters
    ----------
    message : str
    category : Warning subclass
        Default :class:`HamrkqWarning`.
    """
    level = 2  # 1 would be this function, 2 its caller
    frame = sys._getframe(1)
    while frame is not None and any(part in frame.f_code.co_filename for part in _INTERNAL):
        frame = frame.f_back
        level += 1
    warnings.warn(message, category, stacklevel=level)
