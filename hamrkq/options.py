"""The options of an integration: one vocabulary, one validation.

:class:`SolveOptions` holds every option of :func:`hamrkq.solve` that does not
depend on the system's dimension, validated once; :func:`hamrkq.solve`, the
catalogue's ``[integration]`` tables (:func:`check_setting`) and the command
line all go through it, so an option's valid values, default and message are
written here and nowhere else.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping
from dataclasses import dataclass, fields, replace
from typing import Any

from hamrkq._floats import MIN_RTOL
from hamrkq._validate import choice, count, positive, show
from hamrkq.baselines import PREFIX as SCIPY_PREFIX
from hamrkq.baselines import SCIPY_SOLVER_HOMES
from hamrkq.errors import InputError, OptionError
from hamrkq.fixed_step.symplectic import FIXED_STEP_METHODS
from hamrkq.rkq.auto_rules import AUTO_MEMBER, auto_member
from hamrkq.rkq.family import MEMBERS, Z_METHODS, get_member, has_quencher
from hamrkq.rkq.layout import (
    GAMMA_OFF,
    GAMMA_PAPER,
    GAMMA_SHADOW,
    GAMMA_TANGENT,
    QUENCH_NODE,
    QUENCH_REDO,
    RULE_COMPONENTWISE,
    RULE_PRENTICE,
)

__all__ = [
    "BACKENDS",
    "DEFAULT_GAMMA_LIMIT",
    "DEFAULT_MAX_STEPS",
    "GAMMA_MODES",
    "METHOD_NAMES",
    "MIN_RTOL",
    "QUENCHER_PRECISIONS",
    "QUENCH_MODES",
    "TOLERANCE_RULES",
    "Z_METHOD_NAMES",
    "SolveOptions",
    "applicable_settings",
    "check_setting",
    "refused_options",
    "z_method_applies",
]

#: Relative tolerances below this are raised to it (with a warning): below
#: about 100 eps the local error test measures rounding, as in SciPy.
#: Absolute tolerances below this are refused: no double can resolve them
#: (a smaller atol would make every step fail until the step limit).
MIN_ATOL = 1e-300
#: Default step limit (accepted plus rejected attempts): a guard against runs
#: that would never end, far above the ~62 000 steps of the paper's problem.
DEFAULT_MAX_STEPS = 1_000_000
#: Default for ``gamma_limit``: the run stops when the quencher's own
#: estimated error (plus rounding) exceeds this fraction of the tolerance, so
#: that a reported node's true error stays within (1 + 0.05) x tolerance.
DEFAULT_GAMMA_LIMIT = 0.05

QUENCH_MODES = {"node": QUENCH_NODE, "redo": QUENCH_REDO}
TOLERANCE_RULES = {"componentwise": RULE_COMPONENTWISE, "prentice": RULE_PRENTICE}
GAMMA_MODES = {
    "tangent": GAMMA_TANGENT,
    "paper": GAMMA_PAPER,
    "shadow": GAMMA_SHADOW,
    "off": GAMMA_OFF,
}
Z_METHOD_NAMES = tuple(Z_METHODS)
#: The quencher's arithmetic: doubles (with compensated sums), or its stages
#: and f in double-double (hamrkq.rkq.ddarith), below double precision's
#: rounding floor.
QUENCHER_PRECISIONS = ("double", "double-double")
#: Where the RK loop runs: "numba" (compiled), "python" (interpreted), or
#: "auto" (numba when it can be used).
BACKENDS = ("auto", "numba", "python")
#: Every method name :func:`hamrkq.solve` accepts.
METHOD_NAMES = (
    "auto",
    *MEMBERS,
    *FIXED_STEP_METHODS,
    *(SCIPY_PREFIX + name for name in SCIPY_SOLVER_HOMES),
)


@dataclass(frozen=True)
class SolveOptions:
    """Validated options of one integration (those that do not depend on the
    system's dimension; tolerances and ``t_eval`` are checked by
    :func:`hamrkq.solve` against the state).  See :func:`hamrkq.solve` for
    what each means."""

    method: str = "auto"
    quench: str = "node"
    quench_threshold: float = 1.0
    safety: float = 0.9
    tolerance_rule: str = "componentwise"
    global_error_estimate: str | None = None
    z_method: str | None = None  # the member's own quencher (DOP853's for rk34q8)
    z_substeps: int | None = None
    quencher_precision: str | None = None  # "double", unless method="auto" escalates
    first_step: float | None = None
    max_step: float = math.inf
    step: float | None = None
    max_steps: int = DEFAULT_MAX_STEPS
    gamma_limit: float = DEFAULT_GAMMA_LIMIT
    keep_every: int = 1
    backend: str = "auto"

    @classmethod
    def resolve(cls, given: Mapping[str, Any], settings: Mapping[str, Any]) -> SolveOptions:
        """Options from keywords (``None`` = not given) over a problem's
        ``settings`` over the defaults, each validated.

        Raises
        ------
        InputError, InputTypeError, OptionError
            The first invalid option, named with its value.
        """
        # The same options again (every call of a loop over solve) are not
        # checked again: the options are immutable, and the outcome depends
        # only on the values given, each keyed with its type (1, 1.0 and True
        # are equal keys of a dict, and not the same option).  A value that
        # cannot be hashed is checked every time.
        try:
            return _resolved(_given_key(settings, _OPTION_NAMES), _given_key(given))
        except TypeError:  # unhashable
            return cls._resolve(given, settings)

    @classmethod
    def _resolve(cls, given: Mapping[str, Any], settings: Mapping[str, Any]) -> SolveOptions:
        """:meth:`resolve` without the memo."""
        # The defaults are valid: only what a source sets is checked (each
        # check was about 15 us of a tiny problem's call).
        chosen: dict[str, Any] = {}
        for source in (settings, given):
            for key, value in source.items():
                if value is not None and key in _OPTION_NAMES:
                    chosen[key] = value
        options = cls(**{key: _check(key, value) for key, value in chosen.items()})
        if given.get("z_method") is not None:
            _check_z_method_applies(options.method, options.z_method)
        _check_options_apply(options.method, given)
        options.check_combination()
        return options

    def check_combination(self) -> None:
        """Raise :class:`OptionError` where options valid one by one do not go
        together: the shadow estimate with fewer than two quencher steps a
        step, the quencher in double-double without the shadow estimate.
        :meth:`resolve` checks the caller's options; ``method="auto"`` checks
        each of its reruns' (:func:`hamrkq.solve.auto.rerun`), which it
        builds with :func:`dataclasses.replace` and no :meth:`resolve`."""
        if self.method in MEMBERS or self.method == "auto":
            member = get_member(
                # auto's members share their Gamma and steps (tests/test_family.py)
                AUTO_MEMBER if self.method == "auto" else self.method,
                self.z_method,
                self.z_substeps,
            )
            if self.gamma_name == "shadow" and member.z_substeps < 2:
                raise OptionError(
                    "global_error_estimate='shadow' compares the quencher with a track on a "
                    f"mesh z_substeps times coarser: it needs z_substeps >= 2, got "
                    f"{member.z_substeps}"
                )
        if self.double_double and (
            self.method not in (*MEMBERS, "auto") or self.gamma_name != "shadow"
        ):
            raise OptionError(
                "quencher_precision='double-double' needs a quencher whose Gamma comes from "
                "the shadow track (method='auto' or a family member other than 'rk34q8', "
                f"with global_error_estimate='shadow'); got method={self.method!r}, "
                f"global_error_estimate={self.gamma_name!r}"
            )

    @property
    def double_double(self) -> bool:
        """Whether the quencher runs in double-double."""
        return self.quencher_precision == "double-double"

    def member(self):
        """The RKQ family member these options run (:mod:`hamrkq.rkq.family`)."""
        return get_member(self.method, self.z_method, self.z_substeps)

    def with_auto(self, dim: int, tolerance: float) -> SolveOptions:
        """``method="auto"`` replaced by its member for a system of ``dim``
        state variables at ``tolerance``
        (:func:`~hamrkq.rkq.auto_rules.auto_tolerance`) and its first run's
        quencher steps (:func:`~hamrkq.rkq.auto_rules.auto_member`)."""
        if self.method != "auto":
            return self
        # Under a cap (capped_default) the estimate stays None and gamma_name
        # reads "tangent": auto never runs that in double-double by itself
        # (hamrkq.solve.auto.double_double_can_help), and a stop's message
        # can offer the caller the quencher in double-double, which brings
        # the shadow back.
        return _with_member(self, *auto_member(dim, tolerance))

    @property
    def capped_default(self) -> bool:
        """Whether the default estimate of Gamma is the tangent one because the
        caller caps the steps: a ``max_step`` given, no estimate chosen, the
        quencher in double.  The cap takes away the shadow's long steps,
        whose saturation shows where its premise fails (on a very eccentric
        orbit at a loose tolerance, the pair's long steps through the
        pericentre): Kepler at e = 0.9, rtol 1e-3, atol 1e-6 over 300
        periods with max_step=0.143 returned SUCCESS with its last node 22.1
        tolerances off with ``method="auto"``, ``rk78q12`` at e = 0.85 5.8
        off (QA; docs/algorithm.md, "A max_step given by the caller")."""
        return (
            self.global_error_estimate is None
            and self.max_step < math.inf
            and not self.double_double
        )

    @functools.cached_property  # (immutable options; a solve asks it a dozen times)
    def gamma_name(self) -> str:
        """The Gamma estimate: the option, or the method's default (the tangent
        one for a shadow member under a cap, :attr:`capped_default`)."""
        if self.global_error_estimate is not None:
            return self.global_error_estimate
        member = MEMBERS.get(AUTO_MEMBER if self.method == "auto" else self.method)
        if member is None or (member.gamma == "shadow" and self.capped_default):
            return "tangent"
        return member.gamma

    @property
    def is_fixed_step(self) -> bool:
        """Whether the method takes a fixed ``step`` (and no tolerances)."""
        return self.method in FIXED_STEP_METHODS

    def codes(self) -> dict[str, int]:
        """The kernel's codes for the named options."""
        return {
            "quench": QUENCH_MODES[self.quench],
            "rule": TOLERANCE_RULES[self.tolerance_rule],
            "gamma": GAMMA_MODES[self.gamma_name],
        }


def _given_key(values: Mapping[str, Any], names: Any = None) -> tuple:
    """The values set (not None) of ``values`` (of the ``names`` only, if
    given), each with its type: a key of :func:`_resolved`."""
    return tuple(
        (key, type(value), value)
        for key, value in values.items()
        if value is not None and (names is None or key in names)
    )


@functools.lru_cache(maxsize=128)
def _resolved(settings: tuple, given: tuple) -> SolveOptions:
    """:meth:`SolveOptions.resolve` of the values of two :func:`_given_key`
    keys, memoised (an invalid option raises, and is not remembered)."""
    return SolveOptions._resolve(
        {key: value for key, _, value in given}, {key: value for key, _, value in settings}
    )


@functools.lru_cache(maxsize=128)
def _with_member(options: SolveOptions, name: str, substeps: int) -> SolveOptions:
    """``options`` of ``method="auto"`` running the member ``name``, with
    ``substeps`` quencher steps unless given (:meth:`SolveOptions.with_auto`),
    memoised: the options are immutable, and a copy of them costs microseconds
    of every call."""
    return replace(options, method=name, z_substeps=options.z_substeps or substeps)


def _check_z_method_applies(method: str, z_method: str) -> None:
    """``z_method`` given for a method whose quencher it cannot replace: an
    error, not an option silently ignored (it chooses among the 8th-order
    quenchers).  A problem file's ``z_method`` applies where it can."""
    if z_method_applies(method):
        return
    if method not in (*MEMBERS, "auto"):
        raise OptionError(f"z_method={z_method!r} needs an RKQ method; method={method!r} has none")
    eight = ", ".join(repr(k) for k, m in MEMBERS.items() if m.use_z and m.z_order == 8)
    if method == "auto":
        has = "method='auto' runs members with quenchers of order 9 to 12"
    else:
        member = MEMBERS[method]
        has = f"{method!r} has " + (
            f"the order-{member.z_order} quencher {member.quencher.name!r}"
            if member.use_z
            else "no quencher"
        )
    raise OptionError(f"z_method={z_method!r} replaces the quencher of {eight}; {has}")


#: Options that steer a quencher and its estimate Gamma: they mean nothing to
#: a method without one.
QUENCHER_OPTIONS = (
    "quench",
    "quench_threshold",
    "global_error_estimate",
    "z_substeps",
    "quencher_precision",
    "gamma_limit",
)
#: Options of hamrkq's own adaptive step loop (SciPy's solvers have their own
#: safety factor and error norm).
STEP_LOOP_OPTIONS = ("safety", "tolerance_rule")


def refused_options(method: str) -> tuple[tuple[str, ...], str]:
    """The options ``method`` has no use for, and why (for the message).

    Given by keyword, each is an error (:meth:`SolveOptions.resolve`); in a
    problem file's ``[integration]``, a default that applies where it can
    (:func:`applicable_settings`)."""
    if method == "auto":
        return (), ""
    if method == f"{SCIPY_PREFIX}RK34Q8":  # rk34q8 as SciPy's OdeSolver: its options
        return ("z_substeps", "quencher_precision"), (
            "the paper's method as SciPy's OdeSolver: one DOP853 or Cooper-Verner step a "
            "step, in double"
        )
    if method in FIXED_STEP_METHODS:
        refused = ("atol", "rtol", "first_step", "max_step", *QUENCHER_OPTIONS)
        return (*refused, *STEP_LOOP_OPTIONS), (
            "a fixed-step method: no error control, no quencher; give step only"
        )
    if method.startswith(SCIPY_PREFIX):
        return (*QUENCHER_OPTIONS, *STEP_LOOP_OPTIONS), (
            "SciPy's solver, with its own step control and no quencher"
        )
    if method in MEMBERS and not has_quencher(method):
        return QUENCHER_OPTIONS, "the pair alone, without a quencher"
    return (), ""


def applicable_settings(method: str, settings: Mapping[str, Any]) -> dict[str, Any]:
    """A problem file's ``[integration]`` settings that apply to ``method``:
    its ``atol`` means nothing to ``verlet``, whose run ignores it (as
    :func:`hamrkq.solve` does with a problem's defaults)."""
    refused = set(refused_options(method)[0])
    if method not in FIXED_STEP_METHODS:
        refused.add("step")  # solve reads it only for a fixed-step method
    if not z_method_applies(method):
        refused.add("z_method")  # as solve, which applies a file's z_method where it can
    return {key: value for key, value in settings.items() if key not in refused}


def inapplicable_setting(settings: Mapping[str, Any]) -> tuple[str, str] | None:
    """The first setting of a problem file's ``[integration]`` that its own
    method (``method``, else ``"auto"``) has no use for, and why; or a
    fixed-step method without its ``step``.  None if there is none.

    A file's settings are defaults for the method it names: where a caller
    runs another method, those that do not apply to it are left out
    (:func:`applicable_settings`); but a file whose settings do not apply
    to its own method says something it does not do (``z_method`` beside
    ``auto``'s default, ``step`` without a fixed-step method: both ran
    without them, found by QA)."""
    method = str(settings.get("method", "auto"))
    if method in FIXED_STEP_METHODS and settings.get("step") is None:
        return "method", f"method {method!r} is a fixed-step method: its step must be set too"
    refused, why = refused_options(method)
    for key in settings:
        if key in refused:
            return key, f"{key} does not apply to the file's method {method!r} ({why})"
        if key == "step" and method not in FIXED_STEP_METHODS:
            return key, (
                f"step applies only to the fixed-step methods, not to the file's method {method!r}"
            )
        if key == "z_method" and not z_method_applies(method):
            return key, (
                f"z_method chooses among the order-8 quenchers: the file's method {method!r} "
                "has no quencher it can replace"
            )
    return None


def z_method_applies(method: str) -> bool:
    """Whether ``z_method`` (an 8th-order quencher) can replace ``method``'s
    quencher: the paper's ``rk34q8`` (also as SciPy's OdeSolver) and the
    members whose quencher is of order 8."""
    if method == f"{SCIPY_PREFIX}RK34Q8":
        return True
    member = MEMBERS.get(method)
    return member is not None and member.use_z and member.z_order == 8


def _check_options_apply(method: str, given: Mapping[str, Any]) -> None:
    """An option given (by keyword) to a method that has no use for it is an
    error, not silently ignored: ``max_step=1e-3`` with ``gauss4`` ran steps
    of 0.1 without a word."""
    refused, why = refused_options(method)
    for name in refused:
        value = given.get(name)
        if value is not None and not (name == "max_step" and value == math.inf):
            raise OptionError(f"{name}={value!r} does not apply to method={method!r} ({why})")


def _check(key: str, value: Any) -> Any:
    """One option's value, validated (the message names the option)."""
    if key in _NAMES:
        return choice(key, value, _NAMES[key])
    if key in ("first_step", "step"):
        return None if value is None else positive(key, value)
    if key == "max_step":
        return positive(key, value, inf=True)
    if key == "gamma_limit":
        return positive(key, value, inf=True)
    if key == "safety":
        return positive(key, value, upper=1.0)
    if key == "quench_threshold":
        return positive(key, value)
    if key in ("max_steps", "keep_every"):
        return count(key, value)
    if key == "z_substeps":
        return _quencher_steps(count(key, value))
    raise OptionError(f"unknown option {key!r}")  # pragma: no cover - fields are fixed


#: The most quencher steps a step of the pair: the quencher's error falls like
#: ``m^-z`` (z >= 8), so 64 steps already take it 1e14 below one step's;
#: ``z_substeps=10**12`` was accepted, and its first step never ended (QA).
MAX_Z_SUBSTEPS = 1024


def _quencher_steps(value: int) -> int:
    """``z_substeps`` at most :data:`MAX_Z_SUBSTEPS`."""
    if value > MAX_Z_SUBSTEPS:
        raise InputError(
            f"z_substeps must be at most {MAX_Z_SUBSTEPS} (the quencher's error falls like "
            f"m^-z, z >= 8: 64 steps take it 1e14 below one step's), got {value}"
        )
    return value


#: The fields of :class:`SolveOptions`: the keys a problem's settings or a
#: keyword may set.
_OPTION_NAMES = frozenset(f.name for f in fields(SolveOptions))

_NAMES: dict[str, Any] = {
    "method": METHOD_NAMES,
    "quench": QUENCH_MODES,
    "tolerance_rule": TOLERANCE_RULES,
    "global_error_estimate": GAMMA_MODES,
    "z_method": Z_METHOD_NAMES,
    "quencher_precision": QUENCHER_PRECISIONS,
    "backend": BACKENDS,
}


def check_setting(key: str, value: Any) -> None:
    """Check one setting of a problem file's ``[integration]`` table.

    Tolerances (``atol``, ``rtol``: a number or a list of them) are checked
    for their sign here; the problem-file reader checks a list's length
    against the state's, which it knows.

    Raises
    ------
    InputError, InputTypeError, OptionError
        With the key and value named.
    """
    if key in ("atol", "rtol"):
        items = value if isinstance(value, list) and value else [value]
        for item in items:
            ok = not isinstance(item, bool) and isinstance(item, int | float)
            ok = ok and math.isfinite(item) and (item > 0 or (key == "rtol" and item == 0))
            if ok and key == "atol" and item < MIN_ATOL:
                ok = False
            if not ok:
                need = "a positive finite number" if key == "atol" else "a finite number >= 0"
                raise InputError(f"{key} must be {need} (or a list of them), got {show(value)}")
        return
    if key not in _NAMES and key not in _OPTION_NAMES:
        raise OptionError(f"unknown setting {key!r}")
    if isinstance(value, bool) or (key not in _NAMES and isinstance(value, str)):
        raise InputError(f"{key} must be a number, got {show(value)}")
    _check(key, value)
