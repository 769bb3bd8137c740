"""The problem catalogue: TOML files describing classic Hamiltonian problems.

A problem file is data, never code: its expressions go through the restricted
parser of :mod:`hamrkq.symbolic.expressions`.  The format is documented in
``docs/catalogue.md``.  The catalogue's own files live in the repository's
``problems/`` folder, installed as the package ``hamrkq.problems``.
"""

from __future__ import annotations

import math
import re
import tomllib
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from importlib import resources
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np
import sympy as sp

from hamrkq.errors import InputError, InputTypeError, ProblemFileError, ProblemNotFoundError
from hamrkq.symbolic.expressions import check_name, parse_expression
from hamrkq.symbolic.hamiltonian import Hamiltonian

__all__ = ["Problem", "catalogue_dir", "list_problems", "load_problem"]

#: Largest problem file accepted, in bytes.
MAX_FILE_BYTES = 1_000_000

TOP_LEVEL_KEYS = frozenset(
    {
        "name",
        "title",
        "description",
        "references",
        "coordinates",
        "momenta",
        "hamiltonian",
        "parameters",
        "initial",
        "integration",
        "invariants",
        "exact",
        "expected",
        "events",
    }
)
REQUIRED_KEYS = ("name", "coordinates", "momenta", "hamiltonian", "initial")
#: What each ``[integration]`` setting must be.  Checked when the file is read,
#: so that a bad value is reported with the file, line and key, not later by
#: :func:`hamrkq.solve` without them.
INTEGRATION_KINDS = {
    **dict.fromkeys(("method", "quench", "tolerance_rule", "global_error_estimate"), "name"),
    **dict.fromkeys(("z_method",), "name"),
    **dict.fromkeys(("atol", "rtol"), "tolerance"),
    **dict.fromkeys(("first_step", "max_step", "step", "quench_threshold", "safety"), "positive"),
    "max_steps": "count",
}
INTEGRATION_KEYS = frozenset({"t_span", *INTEGRATION_KINDS})


@dataclass(frozen=True, eq=False)
class Problem:
    """A catalogue entry: a Hamiltonian with initial values and settings.

    Attributes
    ----------
    name, title, description : str
    references : tuple of str
    hamiltonian : Hamiltonian
    q0, p0 : ndarray
        Initial values for the current parameter values.
    t_span : tuple of float
    integration : mapping
        Default settings for :func:`hamrkq.solve` (method, atol, rtol, ...).
    invariants : mapping of str to sympy.Expr
        First integrals besides H.
    exact : callable or None
        ``exact(t) -> ndarray (N, 2n)``, the exact solution for these initial
        values and parameters, where the file gives one.
    expected : mapping
        Published reference values, with their sources.
    events : tuple of mapping
        The ``[[events]]`` tables: ``expression`` (a SymPy expression in the
        state, parameters and ``t``), ``direction`` and ``terminal``; the
        default ``events=`` of :func:`hamrkq.solve`.
    parameters : mapping of str to float
        The parameter values in use.
    path : Path or None
        The file it came from.
    """

    name: str
    title: str
    description: str
    references: tuple[str, ...]
    hamiltonian: Hamiltonian
    initial_exprs: tuple[sp.Expr, ...]
    t_span_exprs: tuple[sp.Expr, sp.Expr]
    integration: Mapping[str, Any]
    invariants: Mapping[str, sp.Expr]
    exact_spec: Mapping[str, Any] | None
    expected: Mapping[str, Any]
    parameters: Mapping[str, float]
    path: Path | None = None
    #: The file's key of each initial value ("initial.x" or "initial.q[0]"), for messages.
    initial_keys: tuple[str, ...] = ()
    events: tuple[Mapping[str, Any], ...] = ()
    _values: dict = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        ham = self.hamiltonian
        params = ham.parameter_values(self.parameters)
        subs = dict(zip(ham.parameters, params, strict=True))
        n = ham.n
        keys = list(self.initial_keys) or [
            f"initial.{'qp'[i >= n]}[{i % n}]" for i in range(2 * n)
        ]
        y0 = np.array(
            [self._value(e, subs, k) for e, k in zip(self.initial_exprs, keys, strict=True)]
        )
        t_span = tuple(self._value(e, subs, "integration.t_span") for e in self.t_span_exprs)
        self._values.update(y0=y0, t_span=t_span, params=params)
        y0.setflags(write=False)
        object.__setattr__(self, "integration", MappingProxyType(dict(self.integration)))
        object.__setattr__(self, "invariants", MappingProxyType(dict(self.invariants)))
        object.__setattr__(self, "expected", MappingProxyType(dict(self.expected)))
        object.__setattr__(self, "parameters", MappingProxyType(dict(self.parameters)))

    def _value(self, expr: sp.Expr, subs: Mapping, key: str) -> float:
        """A finite real number, or an error naming the key and the parameters
        (``kepler`` with ``e = 1`` makes ``sqrt((1 + e)/(1 - e))`` infinite)."""
        value = _finite_real(expr.subs(subs))
        if value is None:
            shown = ", ".join(f"{k} = {v:g}" for k, v in self.parameters.items())
            raise ProblemFileError(
                f"{expr} is not a finite real number"
                + (f" for the parameters {shown}" if shown else ""),
                path=self.path,
                key=key,
            )
        return value

    @property
    def y0(self) -> np.ndarray:
        """Initial state, all q then all p."""
        return self._values["y0"]

    @property
    def q0(self) -> np.ndarray:
        """Initial coordinates."""
        return self.y0[: self.hamiltonian.n]

    @property
    def p0(self) -> np.ndarray:
        """Initial momenta."""
        return self.y0[self.hamiltonian.n :]

    @property
    def t_span(self) -> tuple[float, float]:
        """Default time interval."""
        return self._values["t_span"]

    @property
    def parameter_array(self) -> np.ndarray:
        """Parameter values ordered like ``hamiltonian.parameters``."""
        return self._values["params"]

    @property
    def exact(self) -> Callable[[Any], np.ndarray] | None:
        """The exact solution ``t -> (N, 2n)``, or None."""
        if self.exact_spec is None:
            return None
        if "exact" not in self._values:
            self._values["exact"] = _exact_function(self)
        return self._values["exact"]

    def invariant_functions(self) -> dict[str, Callable]:
        """Each invariant as ``f(t, Y) -> (N,)`` at the current parameters."""
        from hamrkq.backends.numeric import vectorized

        params = self.parameter_array
        result = {}
        for name, expr in self.invariants.items():
            fn = vectorized(self.hamiltonian, [expr])
            result[name] = lambda t, Y, fn=fn: fn(t, Y, params)[..., 0]
        return result

    def with_parameters(self, **values: float) -> Problem:
        """The same problem with other parameter values (initial values follow)."""
        unknown = sorted(set(values) - {s.name for s in self.hamiltonian.parameters})
        if unknown:
            raise InputError(f"problem {self.name!r} has no parameter(s) {', '.join(unknown)}")
        ham = self.hamiltonian
        # parameter_values names the parameter and the value of a non-number.
        checked = ham.parameter_values({**self.parameters, **values})
        merged = {s.name: float(v) for s, v in zip(ham.parameters, checked, strict=True)}
        return replace(self, parameters=merged, _values={})

    def __repr__(self) -> str:
        return f"Problem({self.name!r}, n={self.hamiltonian.n}, t_span={self.t_span})"


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
        The file is malformed; the message names the file, the line when known,
        and the key.
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
    problem = _parse_file(path)
    return problem.with_parameters(**parameters) if parameters else problem


# -- parsing ------------------------------------------------------------------


def _parse_file(path: Path) -> Problem:
    size = path.stat().st_size
    if size > MAX_FILE_BYTES:
        raise ProblemFileError(f"file is {size} bytes, the limit is {MAX_FILE_BYTES}", path=path)
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise ProblemFileError(f"not UTF-8 text ({exc.reason})", path=path) from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        match = re.search(r"at line (\d+)", str(exc))
        line = int(match.group(1)) if match else None
        raise ProblemFileError(f"TOML syntax error: {exc}", path=path, line=line) from None
    except RecursionError:  # tomllib recurses once per nested array or table
        raise ProblemFileError("TOML nested too deeply", path=path) from None
    return _FileReader(path, text, data).problem()


class _FileReader:
    """Validates the parsed TOML of one file and builds the Problem."""

    def __init__(self, path: Path, text: str, data: dict):
        self.path, self.text, self.data = path, text, data

    def error(self, message: str, key: str) -> ProblemFileError:
        return ProblemFileError(message, path=self.path, key=key, line=self._line(key))

    def _line(self, key: str) -> int | None:
        """Best-effort line number of a dotted key (tomllib gives none)."""
        key = re.sub(r"\[\d+\]$", "", key)  # "initial.q[0]": the line of "q = [...]"
        *section, last = key.split(".")
        table = ".".join(section)
        current = ""
        for number, line in enumerate(self.text.splitlines(), start=1):
            stripped = line.strip()
            header = re.match(r"^\[\s*([^\]]+?)\s*\]", stripped)
            if header:
                current = header.group(1)
                if current == key:
                    return number
            elif current == table and re.match(rf"^\"?{re.escape(last)}\"?\s*=", stripped):
                return number
        return None

    def expr(self, text: Any, symbols: Mapping[str, sp.Symbol], key: str) -> sp.Expr:
        return parse_expression(text, symbols, path=self.path, key=key, line=self._line(key))

    def table(self, key: str) -> dict:
        value = self.data.get(key, {})
        if not isinstance(value, dict):
            raise self.error(f"must be a table, got {type(value).__name__}", key)
        return value

    def names(self, key: str) -> list[str]:
        value = self.data[key]
        if not isinstance(value, list) or not value:
            raise self.error("must be a non-empty list of names", key)
        for item in value:
            reason = check_name(item)
            if reason:
                raise self.error(f"bad name: {reason}", key)
        return value

    def header(self) -> str:
        """Check the top-level keys and the name; returns the name."""
        data = self.data
        unknown = sorted(set(data) - TOP_LEVEL_KEYS)
        if unknown:
            raise self.error(f"unknown key(s): {', '.join(unknown)}", unknown[0])
        for key in REQUIRED_KEYS:
            if key not in data:
                raise ProblemFileError("required key is missing", path=self.path, key=key)
        name = data["name"]
        if name != self.path.stem:
            raise self.error(f"name {name!r} must equal the file stem {self.path.stem!r}", "name")
        return name

    def state_names(self) -> tuple[list[str], list[str]]:
        """``coordinates`` and ``momenta``, checked, of equal length."""
        q_names, p_names = self.names("coordinates"), self.names("momenta")
        if len(q_names) != len(p_names):
            raise self.error(
                f"{len(q_names)} coordinate{'s' if len(q_names) != 1 else ''} "
                f"({', '.join(q_names)}) but {len(p_names)} momenta ({', '.join(p_names)}): "
                "every coordinate needs its conjugate momentum, listed in the same order",
                "momenta",
            )
        return q_names, p_names

    def problem(self) -> Problem:
        data = self.data
        name = self.header()
        q_names, p_names = self.state_names()
        param_table = self.table("parameters")
        param_names = list(param_table)
        for pname in param_names:
            reason = check_name(pname)
            if reason:
                raise self.error(f"bad parameter name: {reason}", f"parameters.{pname}")
        all_names = [*q_names, *p_names, *param_names]
        repeated = sorted({n for n in all_names if all_names.count(n) > 1})
        if repeated:
            raise self.error(f"names declared twice: {', '.join(repeated)}", "coordinates")
        symbols = {n: sp.Symbol(n, real=True) for n in all_names}
        t = sp.Symbol("t", real=True)
        params_only = {n: symbols[n] for n in param_names}
        defaults = {}
        for pname, value in param_table.items():
            value_expr = self.expr(value, {}, f"parameters.{pname}")
            defaults[pname] = _finite_real(value_expr)
            if defaults[pname] is None:
                key = f"parameters.{pname}"
                raise self.error(f"{value_expr} is not a finite real number", key)
        H = self.expr(data["hamiltonian"], {**symbols, "t": t}, "hamiltonian")
        try:
            ham = Hamiltonian(
                H,
                q=[symbols[n] for n in q_names],
                p=[symbols[n] for n in p_names],
                parameters={symbols[n]: defaults[n] for n in param_names},
                t=t,
                name=name,
            )
        except InputError as exc:
            raise self.error(str(exc), "hamiltonian") from None
        init_exprs, init_keys = self.initial(q_names, p_names, params_only)
        integration = self.table("integration")
        extra = sorted(set(integration) - INTEGRATION_KEYS)
        if extra:
            raise self.error(f"unknown key(s): {', '.join(extra)}", f"integration.{extra[0]}")
        for key, value in integration.items():
            if key != "t_span":
                self.setting(key, value)
        span = integration.pop("t_span", None)
        if not isinstance(span, list) or len(span) != 2:
            raise self.error("t_span must be a list of two values", "integration.t_span")
        span_exprs = tuple(self.expr(v, params_only, "integration.t_span") for v in span)
        state_syms = {**symbols, "t": t}
        invariants = {}
        for iname, text in self.table("invariants").items():
            invariants[iname] = self.expr(text, state_syms, f"invariants.{iname}")
        exact = self.exact_spec({**params_only, "t": t}, len(q_names))
        events = self.events(state_syms)
        references = data.get("references", [])
        if not isinstance(references, list) or not all(isinstance(r, str) for r in references):
            raise self.error("must be a list of strings", "references")
        for key in ("title", "description"):
            if not isinstance(data.get(key, ""), str):
                raise self.error(f"must be a string, got {type(data[key]).__name__}", key)
        return Problem(
            name=name,
            title=str(data.get("title", name)),
            description=str(data.get("description", "")),
            references=tuple(references),
            hamiltonian=ham,
            initial_exprs=tuple(init_exprs),
            initial_keys=tuple(init_keys),
            t_span_exprs=span_exprs,
            integration=integration,
            invariants=invariants,
            exact_spec=exact,
            expected=self.table("expected"),
            parameters=defaults,
            path=self.path,
            events=events,
        )

    def initial(
        self, q_names: list[str], p_names: list[str], params: Mapping[str, sp.Symbol]
    ) -> tuple[list[sp.Expr], list[str]]:
        """``[initial]``, bound by the problem's own names (``x = 1.0``) or by the
        lists ``q = [...]``, ``p = [...]``: the expressions in the state's order,
        and the key of each."""
        initial = self.table("initial")
        state = [*q_names, *p_names]
        listed = [k for k in initial if k in ("q", "p") and k not in state]
        named = [k for k in initial if k not in listed]
        if listed and named:
            raise self.error(
                f"mixes the lists {' and '.join(listed)} with the names "
                f"{', '.join(named)}: bind every value by name ({' = ..., '.join(state)} = ...) "
                "or give the lists q = [...] and p = [...], not both",
                f"initial.{named[0]}",
            )
        if not named:
            exprs, keys = [], []
            for part, count in (("q", len(q_names)), ("p", len(p_names))):
                values = initial.get(part)
                if not isinstance(values, list) or len(values) != count:
                    raise self.error(
                        f"must be a list of {count} values, got {_shown(values)}",
                        f"initial.{part}",
                    )
                keys += [f"initial.{part}[{i}]" for i in range(count)]
                exprs += [
                    self.expr(v, params, k) for v, k in zip(values, keys[-count:], strict=True)
                ]
            return exprs, keys
        unknown = [k for k in named if k not in state]
        if unknown:
            hint = " (a parameter: set it in [parameters])" if unknown[0] in params else ""
            raise self.error(
                f"{unknown[0]} = {_shown(initial[unknown[0]])}: unknown name{hint}; "
                f"[initial] binds the coordinates and momenta {', '.join(state)}",
                f"initial.{unknown[0]}",
            )
        missing = [k for k in state if k not in initial]
        if missing:
            raise self.error(f"no initial value for {', '.join(missing)}", "initial")
        exprs = []
        for key in state:
            value = initial[key]
            if isinstance(value, list):
                # x = [1.0] reads as one value; more is a vector given to a scalar
                if len(value) != 1:
                    raise self.error(
                        f"{key} = {_shown(value)}: one value expected, got a list of {len(value)}",
                        f"initial.{key}",
                    )
                value = value[0]
            exprs.append(self.expr(value, params, f"initial.{key}"))
        return exprs, [f"initial.{key}" for key in state]

    def events(self, symbols: Mapping[str, sp.Symbol]) -> tuple[dict[str, Any], ...]:
        """The ``[[events]]`` tables, expressions through the safe parser."""
        tables = self.data.get("events", [])
        if not isinstance(tables, list) or not all(isinstance(e, dict) for e in tables):
            raise self.error("must be an array of tables ([[events]])", "events")
        events = []
        for k, table in enumerate(tables):
            key = f"events[{k}]"
            extra = sorted(set(table) - {"expression", "direction", "terminal"})
            if extra or "expression" not in table:
                raise self.error(
                    "an event has 'expression' and may have 'direction' and 'terminal' "
                    f"(got {', '.join(sorted(table))})",
                    key,
                )
            direction = table.get("direction", 0)
            if isinstance(direction, bool) or not isinstance(direction, int | float):
                raise self.error(f"direction must be a number, got {direction!r}", key)
            terminal = table.get("terminal", False)
            if not isinstance(terminal, bool) and not (
                isinstance(terminal, int) and terminal >= 0
            ):
                raise self.error(f"terminal must be a bool or a count, got {terminal!r}", key)
            expr = self.expr(table["expression"], symbols, f"{key}.expression")
            events.append({"expression": expr, "direction": direction, "terminal": terminal})
        return tuple(events)

    def setting(self, key: str, value: Any) -> None:
        """Check one ``[integration]`` value with :func:`hamrkq.options.check_setting`,
        the same checks :func:`hamrkq.solve` makes."""
        from hamrkq.errors import HamrkqError
        from hamrkq.options import check_setting

        try:
            check_setting(key, value)
        except HamrkqError as exc:
            raise self.error(str(exc), f"integration.{key}") from None

    def exact_spec(self, symbols: Mapping[str, sp.Symbol], n: int) -> dict | None:
        table = self.table("exact")
        if not table:
            return None
        if "builtin" in table:
            from hamrkq.catalogue.exact import BUILTIN_EXACT

            builtin = table["builtin"]
            if set(table) != {"builtin"}:
                raise self.error("builtin excludes other keys", "exact")
            if builtin not in BUILTIN_EXACT:
                known = ", ".join(sorted(BUILTIN_EXACT))
                raise self.error(f"unknown builtin {builtin!r} (known: {known})", "exact.builtin")
            return {"builtin": builtin}
        if set(table) != {"q", "p"}:
            raise self.error("must have either 'builtin' or both 'q' and 'p'", "exact")
        exprs = []
        for part in ("q", "p"):
            values = table[part]
            if not isinstance(values, list) or len(values) != n:
                raise self.error(f"must be a list of {n} expressions", f"exact.{part}")
            exprs += [self.expr(v, symbols, f"exact.{part}[{i}]") for i, v in enumerate(values)]
        return {"expressions": tuple(exprs)}


def _shown(value: Any) -> str:
    """A TOML value as the user wrote it, shortened for a message."""
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _finite_real(expr: sp.Expr) -> float | None:
    """The value of a closed-form expression as a float, or None when it is not
    a finite real number (``1/(1 - e)`` at ``e = 1``, ``acos(2)``, ...)."""
    try:
        value = complex(sp.N(expr, 17))
    except (TypeError, ValueError):  # free symbols, zoo
        return None
    if value.imag != 0 or not math.isfinite(value.real):
        return None
    return value.real


def _exact_function(problem: Problem) -> Callable[[Any], np.ndarray]:
    spec = problem.exact_spec
    ham = problem.hamiltonian
    params = problem.parameter_array
    if "builtin" in spec:
        from hamrkq.catalogue.exact import BUILTIN_EXACT

        solver = BUILTIN_EXACT[spec["builtin"]]
        y0 = problem.y0.copy()
        named = {s.name: float(v) for s, v in zip(ham.parameters, params, strict=True)}
        t0 = problem.t_span[0]

        def exact(t):
            return solver(np.atleast_1d(np.asarray(t, dtype=float)), y0, named, t0=t0)

        return exact
    raw = sp.lambdify((ham.t, list(ham.parameters)), list(spec["expressions"]), dummify=True)

    def exact(t):
        t = np.atleast_1d(np.asarray(t, dtype=float))
        columns = raw(t, params)
        return np.column_stack([np.broadcast_to(c, t.shape) for c in columns]).astype(float)

    return exact
