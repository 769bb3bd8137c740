"""Property-based tests of the failure policy (issue 17).

Random bad values, shapes and option mixes are thrown at :func:`hamrkq.solve`,
:class:`hamrkq.Hamiltonian` and the problem-file loader.  Each call must end
in one of the two documented ways:

- an exception from :mod:`hamrkq.errors` (a ``HamrkqError``), or
- a :class:`~hamrkq.Solution` whose status is honest: ``SUCCESS`` only with
  the last node at the end of the interval and every value finite; any other
  status with a message and ``partial`` set.

Never another exception type (``ValueError`` from NumPy, ``KeyError``,
``OverflowError``, SymPy's ``SympifyError``, ...).  The examples are bounded
(few steps, small numbers of examples) so that the module runs in seconds.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
import sympy as sp
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import hamrkq
from hamrkq.catalogue.problems import load_problem
from hamrkq.errors import HamrkqError
from hamrkq.result import Solution, Status

pytestmark = pytest.mark.filterwarnings("ignore::hamrkq.errors.HamrkqWarning")

FUZZ = settings(
    max_examples=120,
    deadline=None,
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)

Q, P, A = sp.symbols("q p a", real=True)
HAM = hamrkq.Hamiltonian(P**2 / 2 - A * sp.cos(Q), [Q], [P], {A: 1.0})

#: Values of every kind a caller might pass by mistake.
BAD_SCALARS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.floats(min_value=-1e3, max_value=1e3),
    st.integers(min_value=-(10**400), max_value=10**400),
    st.sampled_from(
        [
            None,
            True,
            "1e-6",
            b"1",
            "",
            1j,
            complex(1, 0),
            sp.oo,
            sp.nan,
            sp.zoo,
            sp.I,
            sp.Symbol("z"),
            sp.sqrt(2),
            sp.Integer(10) ** 400,
            sp.Rational(1, 3),
            np.float32(1.5),
            np.int64(3),
            np.array(np.nan),
            object(),
            {},
            [],
            (),
            5e-324,
            1e-320,
            -0.0,
            1e308,
        ]
    ),
)
BAD_VALUES = st.one_of(
    BAD_SCALARS,
    st.lists(BAD_SCALARS, max_size=4),
    st.tuples(BAD_SCALARS, BAD_SCALARS),
    st.builds(
        lambda shape, fill: np.full(shape, fill),
        st.lists(st.integers(0, 3), max_size=3).map(tuple),
        st.floats(allow_nan=True, allow_infinity=True),
    ),
    st.dictionaries(st.sampled_from(["a", "b", "q", 1, A]), BAD_SCALARS, max_size=2),
)

OPTIONS = {
    "method": st.one_of(
        st.sampled_from(["rk34q8", "rk34", "gauss4", "midpoint", "verlet", "scipy:DOP853"]),
        BAD_VALUES,
    ),
    "atol": BAD_VALUES,
    "rtol": BAD_VALUES,
    "quench": st.one_of(st.sampled_from(["node", "step", "off"]), BAD_VALUES),
    "quench_threshold": BAD_VALUES,
    "safety": BAD_VALUES,
    "tolerance_rule": BAD_VALUES,
    "global_error_estimate": BAD_VALUES,
    "z_method": BAD_VALUES,
    "first_step": BAD_VALUES,
    "max_step": BAD_VALUES,
    "step": BAD_VALUES,
    "gamma_limit": BAD_VALUES,
    "keep_every": BAD_VALUES,
    "t_eval": BAD_VALUES,
    "parameters": BAD_VALUES,
    "max_steps": st.one_of(st.integers(min_value=1, max_value=60), BAD_VALUES),
}


def assert_honest(sol: Solution, t_end: float | None = None) -> None:
    """A returned solution tells the truth about how the run ended."""
    assert isinstance(sol, Solution)
    assert isinstance(sol.status, Status)
    assert sol.partial is (not sol.success)
    assert len(sol) >= 1 and sol.y.shape == (len(sol), 2 * sol.n)
    if sol.success:
        assert np.all(np.isfinite(sol.y))
        if t_end is not None:
            assert sol.t[-1] == pytest.approx(t_end, rel=1e-12, abs=1e-12)
    else:
        assert sol.message


def call(function, *args, **kwargs):
    """``function(...)``; a HamrkqError is an acceptable answer, nothing else is."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # NumPy's and hamrkq's warnings are not the point
        try:
            return function(*args, **kwargs)
        except HamrkqError:
            return None


@FUZZ
@given(
    q0=st.one_of(BAD_VALUES, st.just([0.5])),
    p0=st.one_of(BAD_VALUES, st.just([0.0])),
    t_span=st.one_of(BAD_VALUES, st.just((0.0, 1.0))),
    options=st.fixed_dictionaries({}, optional=OPTIONS),
)
def test_solve_answers_bad_input_with_a_typed_error_or_an_honest_status(q0, p0, t_span, options):
    options.setdefault("max_steps", 50)  # keep every run short
    sol = call(hamrkq.solve, HAM, q0, p0, t_span, backend="python", **options)
    if sol is not None:
        assert_honest(sol, float(t_span[1]) if "t_eval" not in options else None)


@FUZZ
@given(
    options=st.fixed_dictionaries(
        {"method": st.sampled_from(["rk34q8", "rk34"])},
        optional={
            "atol": st.floats(min_value=1e-320, max_value=1e3),
            "rtol": st.floats(min_value=0, max_value=1e3),
            "t_span": st.tuples(
                st.floats(-1e6, 1e6, allow_nan=False), st.floats(-1e6, 1e6, allow_nan=False)
            ),
            "first_step": st.floats(min_value=1e-300, max_value=10),
            "safety": st.floats(min_value=-1, max_value=2),
            "gamma_limit": st.floats(min_value=0, max_value=math.inf),
        },
    ),
    q0=st.floats(-1e200, 1e200),
)
def test_solve_with_plausible_but_extreme_numbers_reports_an_honest_status(options, q0):
    sol = call(hamrkq.solve, HAM, [q0], [0.0], max_steps=40, backend="python", **options)
    if sol is not None:
        assert_honest(sol, options.get("t_span", (0, 1))[1])


EXPRESSIONS = st.sampled_from(
    [
        P**2 / 2 + Q**2,
        "p**2/2",
        [P**2, Q],
        sp.Matrix([P, Q]),
        sp.Eq(P, Q),
        sp.Function("f")(Q) + P**2,
        sp.I * Q + P**2,
        sp.oo * Q,
        sp.nan + P,
        sp.zoo * P,
        P**2 + sp.Symbol("w") * Q,
        sp.Integral(Q, (Q, 0, 1)) * P,
        P**2 / 2 - A * sp.cos(Q),
        1.5,
        None,
        True,
        sp.Derivative(sp.Function("g")(Q), Q) + P,
        sp.Piecewise((Q, Q > 0), (-Q, True)) + P**2,
    ]
)


@FUZZ
@given(
    H=EXPRESSIONS,
    q=st.sampled_from([[Q], Q, [], [Q, Q], ["q"], [P], None, 3, [sp.Symbol("x")]]),
    p=st.sampled_from([[P], P, [], ["p"], [Q], None, [P, sp.Symbol("v")]]),
    parameters=st.one_of(st.none(), st.just({A: 1.0}), st.just([A]), st.just("a"), BAD_VALUES),
)
def test_hamiltonian_answers_bad_input_with_a_typed_error(H, q, p, parameters):
    ham = call(hamrkq.Hamiltonian, H, q, p, parameters)
    if ham is not None:
        assert isinstance(ham, hamrkq.Hamiltonian) and ham.n >= 1


TOML_VALUES = st.one_of(
    st.sampled_from(
        [
            '"p**2/2 + q**2/2"',
            '"exp(exp(exp(1000)))*q"',
            '"q.__class__"',
            '"1/0"',
            '"sqrt(-1)"',
            "\"__import__('os')\"",
            '"a"',
            '"x"',
            "1e400",
            "nan",
            "inf",
            "-inf",
            "0",
            "1",
            "-1",
            "[]",
            "[1, 2]",
            '["q"]',
            '["p", "p"]',
            '["t"]',
            '["__x"]',
            "{}",
            "{ q = 1 }",
            "true",
            '"""multi\nline"""',
            "1979-05-27",
            "[[1]]",
            '"' + "+".join(["q"] * 3000) + '"',
            '"' + "(" * 70 + "q" + ")" * 70 + '"',
        ]
    ),
    st.floats().map(lambda x: repr(x).replace("inf", "inf").replace("nan", "nan")),
    st.text(alphabet='qpa+-*/()0123456789.e "[]', max_size=20).map(lambda s: repr(s)),
)

KEYS = [
    "name",
    "coordinates",
    "momenta",
    "hamiltonian",
    "initial.q",
    "initial.p",
    "parameters.a",
    "integration.t_span",
    "integration.method",
    "integration.atol",
    "integration.rtol",
    "integration.max_steps",
    "integration.step",
    "invariants.E",
    "exact.q",
    "unknown",
    "integration.unknown",
]

BASE = {
    "name": '"fuzz"',
    "coordinates": '["q"]',
    "momenta": '["p"]',
    "hamiltonian": '"p**2/2 - a*cos(q)"',
    "parameters.a": "1.0",
    "initial.q": "[0.5]",
    "initial.p": "[0]",
    "integration.t_span": "[0, 1]",
}


def render(entries: dict[str, str]) -> str:
    """A TOML file from dotted keys (top-level keys first, then one table each)."""
    lines = [f"{k} = {v}" for k, v in entries.items() if "." not in k]
    tables: dict[str, list[str]] = {}
    for key, value in entries.items():
        if "." in key:
            table, leaf = key.split(".", 1)
            tables.setdefault(table, []).append(f"{leaf} = {value}")
    for table, body in tables.items():
        lines += ["", f"[{table}]", *body]
    return "\n".join(lines) + "\n"


@FUZZ
@given(
    changes=st.dictionaries(st.sampled_from(KEYS), TOML_VALUES, max_size=3),
    removed=st.lists(st.sampled_from(list(BASE)), max_size=1),
)
def test_problem_files_load_or_raise_a_typed_error(tmp_path_factory, changes, removed):
    entries = {k: v for k, v in BASE.items() if k not in removed}
    entries.update(changes)
    path = tmp_path_factory.mktemp("fuzz") / "fuzz.toml"
    path.write_text(render(entries), encoding="utf-8")
    problem = call(load_problem, str(path))
    if problem is None:
        return
    sol = call(hamrkq.solve, problem, max_steps=30, backend="python")
    if sol is not None:
        assert_honest(sol, float(problem.t_span[1]))
