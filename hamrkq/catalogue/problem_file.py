"""Reading one problem file: the TOML format, checked key by key.

A problem file is data, never code: its expressions go through the restricted
parser of :mod:`hamrkq.symbolic.expressions`.  :func:`parse_file` reads a file
and returns its :class:`~hamrkq.catalogue.problem.Problem`; every error names
the file, the key and, where it can be found, the line.  The format is
documented in ``docs/catalogue.md``.
"""

from __future__ import annotations

import re
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import sympy as sp

from hamrkq.catalogue.problem import Problem, finite_real
from hamrkq.errors import ExpressionError, InputError, ProblemFileError
from hamrkq.symbolic.expressions import check_name, parse_expression
from hamrkq.symbolic.hamiltonian import Hamiltonian

__all__ = [
    "ENERGY_NAMES",
    "INTEGRATION_KEYS",
    "INTEGRATION_KINDS",
    "MAX_FILE_BYTES",
    "REQUIRED_KEYS",
    "TOP_LEVEL_KEYS",
    "energy_name_error",
    "parse_file",
]

#: Names an invariant may not take: the energy's own rows.  ``hamrkq show``
#: lists H as the invariant "H", the run's table has "max |H - H(0)|", and
#: the diagnostics summarise it as "energy" (``Diagnostics.table``'s "energy
#: error"); an invariant named either replaced H's row or printed a second
#: row under the same label.
ENERGY_NAMES = ("H", "energy")


def energy_name_error(name: str) -> str | None:
    """Why ``name`` cannot name an invariant, or ``None`` if it can."""
    if name not in ENERGY_NAMES:
        return None
    return (
        f"an invariant may not be named {name!r}: 'H' and 'energy' name the energy, "
        "which is always checked and reported on its own row; give the invariant another name"
    )


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


def parse_file(path: Path) -> Problem:
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
        #: Each declared name's role, for messages ("the coordinate", ...).
        self.roles: dict[str, str] = {}

    def error(self, message: str, key: str) -> ProblemFileError:
        return ProblemFileError(message, path=self.path, key=key, line=self._line(key))

    def _line(self, key: str) -> int | None:
        """Best-effort line number of a dotted key (tomllib gives none)."""
        entry = re.match(r"^(\w+)\[(\d+)\](?:\.(\w+))?$", key)
        if entry:  # "events[1].expression": in the second [[events]] table
            return self._entry_line(entry.group(1), int(entry.group(2)), entry.group(3))
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

    def _entry_line(self, array: str, index: int, key: str | None) -> int | None:
        """The line of ``key`` in the ``index``-th ``[[array]]`` table (of
        its header without a key); the ``[[events]]`` tables' refusals had
        none (QA)."""
        seen, inside = -1, False
        for number, line in enumerate(self.text.splitlines(), start=1):
            stripped = line.strip()
            if stripped.startswith("["):
                inside = re.match(rf"^\[\[\s*{re.escape(array)}\s*\]\]", stripped) is not None
                seen += inside
                inside = inside and seen == index
                if inside and key is None:
                    return number
            elif inside and re.match(rf"^\"?{re.escape(key)}\"?\s*=", stripped):
                return number
        return None

    def expr(self, text: Any, symbols: Mapping[str, sp.Symbol], key: str) -> sp.Expr:
        try:
            return parse_expression(text, symbols, path=self.path, key=key, line=self._line(key))
        except ExpressionError as exc:
            # The parser's "unknown name (not a declared symbol, t, pi or E)"
            # is true of the Hamiltonian; elsewhere fewer names are allowed.
            scope = self.scope(key)
            if scope is None or not exc.detail.startswith("unknown name"):
                raise
            name = exc.piece
            where = "" if str(text).strip() == name else f" (in {_shown(text)})"
            if name not in self.roles and name != "t":
                message = f"unknown name {name!r}{where}: {scope}"
            else:
                what = f"{self.roles[name]} {name!r}" if name in self.roles else "the time t"
                message = f"{what}{where} is not allowed here: {scope}"
            error = ExpressionError(message, path=self.path, key=key, line=self._line(key))
            error.piece = name
            raise error from None

    def scope(self, key: str) -> str | None:
        """What an expression at ``key`` may use, where that is less than
        every declared name and ``t`` (None there)."""
        params = [name for name, role in self.roles.items() if role == "the parameter"]
        listed = f"the parameters ({', '.join(params)}) and " if params else ""
        constants = "constants (numbers, pi, E and the functions of them)"
        if key.startswith("parameters."):
            return (
                f"a parameter's value is one of the {constants}, not an expression of other "
                "parameters, the coordinates, momenta or t"
            )
        if key.startswith("initial."):
            return f"initial values may use {listed}{constants}, not the coordinates, momenta or t"
        if key == "integration.t_span":
            return f"t_span may use {listed}{constants}, not the coordinates, momenta or t"
        if key.startswith("exact."):
            return (
                f"the exact solution may use t, {listed}{constants}, not the coordinates or "
                "momenta"
            )
        return None

    def invariants(self, symbols: Mapping[str, sp.Symbol]) -> dict[str, sp.Expr]:
        """The ``[invariants]`` table, each parsed; none may be named like
        the energy (:data:`ENERGY_NAMES`)."""
        invariants = {}
        for name, text in self.table("invariants").items():
            reason = energy_name_error(name)
            if reason:
                raise self.error(reason, f"invariants.{name}")
            invariants[name] = self.expr(text, symbols, f"invariants.{name}")
        return invariants

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
        self.roles = {
            **dict.fromkeys(q_names, "the coordinate"),
            **dict.fromkeys(p_names, "the momentum"),
            **dict.fromkeys(param_names, "the parameter"),
        }
        t = sp.Symbol("t", real=True)
        params_only = {n: symbols[n] for n in param_names}
        defaults = {}
        for pname, value in param_table.items():
            value_expr = self.expr(value, {}, f"parameters.{pname}")
            defaults[pname] = finite_real(value_expr)
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
                self.setting(key, value, [*q_names, *p_names])
        self.settings_apply(integration)
        span = integration.pop("t_span", None)
        if not isinstance(span, list) or len(span) != 2:
            raise self.error("t_span must be a list of two values", "integration.t_span")
        span_exprs = tuple(self.expr(v, params_only, "integration.t_span") for v in span)
        state_syms = {**symbols, "t": t}
        invariants = self.invariants(state_syms)
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
        if set(initial) == {"q", "p"} and all(isinstance(v, list) for v in initial.values()):
            # The two lists, also where a coordinate is named q or a momentum
            # p (x and p: "mixes the lists q with the names p", found by QA):
            # read by name, they would bind a name that is not the state's or
            # leave one out, but where the names are q and p themselves, and
            # then both readings are the same.
            listed, named = ["q", "p"], []
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

    def setting(self, key: str, value: Any, state: list[str]) -> None:
        """Check one ``[integration]`` value with :func:`hamrkq.options.check_setting`,
        the same checks :func:`hamrkq.solve` makes, and a tolerance's length
        (one number, or one for each of the ``state``'s components)."""
        from hamrkq.errors import HamrkqError
        from hamrkq.options import check_setting

        try:
            check_setting(key, value)
        except HamrkqError as exc:
            raise self.error(str(exc), f"integration.{key}") from None
        if (
            key in ("atol", "rtol")
            and isinstance(value, list)
            and len(value) not in (1, len(state))
        ):
            raise self.error(
                f"{key} = {_shown(value)}: one number, or a list of {len(state)} (one for each "
                f"of {', '.join(state)}), got a list of {len(value)}",
                f"integration.{key}",
            )

    def settings_apply(self, integration: Mapping[str, Any]) -> None:
        """Refuse ``[integration]`` settings its own method has no use for
        (:func:`hamrkq.options.inapplicable_setting`)."""
        from hamrkq.options import inapplicable_setting

        found = inapplicable_setting({k: v for k, v in integration.items() if k != "t_span"})
        if found is not None:
            key, why = found
            raise self.error(why, f"integration.{key}")

    def exact_spec(self, symbols: Mapping[str, sp.Symbol], n: int) -> dict | None:
        table = self.table("exact")
        if not table:
            return None
        if "builtin" in table:
            from hamrkq.catalogue.exact import BUILTIN_ASSUMES, BUILTIN_EXACT

            builtin = table["builtin"]
            if set(table) != {"builtin"}:
                raise self.error("builtin excludes other keys", "exact")
            if not isinstance(builtin, str) or builtin not in BUILTIN_EXACT:
                known = ", ".join(sorted(BUILTIN_EXACT))
                raise self.error(f"unknown builtin {builtin!r} (known: {known})", "exact.builtin")
            dim, assumes = BUILTIN_ASSUMES[builtin]
            if dim != 2 * n:
                raise self.error(
                    f"the builtin {builtin!r} is the flow of {assumes}, {dim // 2} degree(s) "
                    f"of freedom; this problem has {n}",
                    "exact.builtin",
                )
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
