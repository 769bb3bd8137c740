"""The problem catalogue: TOML files describing classic Hamiltonian problems.

A problem file is data, never code: its expressions go through the restricted
parser of :mod:`hamrkq.symbolic.expressions`.  The format is documented in
``docs/catalogue.md``.  The catalogue's own files live in the repository's
``problems/`` folder, installed as the package ``hamrkq.problems``.

This module finds and loads them (:func:`load_problem`); a file is read by
:mod:`hamrkq.catalogue.problem_file` into a :class:`~hamrkq.catalogue.problem.Problem`.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from hamrkq.catalogue.problem import Problem
from hamrkq.catalogue.problem_file import MAX_FILE_BYTES, parse_file
from hamrkq.errors import InputTypeError, ProblemNotFoundError

__all__ = ["MAX_FILE_BYTES", "Problem", "catalogue_dir", "list_problems", "load_problem"]


def catalogue_dir() -> Path:
    """The folder holding the catalogue's TOML files."""
    try:
        folder = resources.files("hamrkq.problems")
        path = Path(str(folder))
        if any(path.glob("*.toml")):
            return path
    except (ModuleNotFoundError, TypeError):
        pass
    # A source checkout without installation: problems/ beside the package.
    return Path(__file__).resolve().parents[2] / "problems"


def list_problems() -> list[str]:
    """Names of the catalogue's problems, sorted."""
    return sorted(path.stem for path in catalogue_dir().glob("*.toml"))


def load_problem(name_or_path: str | Path, **parameters: float) -> Problem:
    """Load a problem by catalogue name or from a ``.toml`` file.

    Parameters
    ----------
    name_or_path : str or Path
        A catalogue name (see :func:`list_problems`) or a path to a file.
    **parameters : float
        Parameter values overriding the file's defaults.

    Raises
    ------
    ProblemNotFoundError
        Neither a catalogue entry nor an existing file.
    ProblemFileError
        The file is malformed, or its ``[exact]`` solution does not solve
        Hamilton's equations at these parameter values; the message names the
        file, the line when known, and the key.
    InputError, InputTypeError
        A parameter override names no parameter of the problem, or its value
        is not a finite real number.
    """
    if not isinstance(name_or_path, str | Path):
        raise InputTypeError(
            f"name_or_path must be a catalogue name or a path, got {name_or_path!r}"
        )
    path = Path(name_or_path)
    text_name = str(name_or_path)
    # A bare name is a catalogue entry unless a *file* of that name exists
    # (a directory called "kepler" in the working directory must not hide it).
    looks_like_path = path.suffix == ".toml" or "/" in text_name or "\\" in text_name
    if not (looks_like_path or path.is_file()):
        path = catalogue_dir() / f"{text_name}.toml"
        if not path.is_file():
            names = ", ".join(list_problems())
            raise ProblemNotFoundError(
                f"no problem named {text_name!r} in the catalogue (known: {names}) "
                "and no such file"
            )
    elif not path.is_file():
        why = "is not a file" if path.exists() else "does not exist"
        raise ProblemNotFoundError(f"problem file {text_name!r} {why}")
    problem = parse_file(path)
    if parameters:
        problem = problem.with_parameters(**parameters)
    problem.exact  # noqa: B018 - checks [exact] against Hamilton's equations
    return problem
