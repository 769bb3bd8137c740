"""The Taylor tape (hamrkq.symbolic.taylor) and its interpreter (hamrkq.rkq.taylor).

Coefficients are checked against exact ones: the Lie series of the vector
field differentiated by SymPy (every operation of the tape, order 5), and
closed-form solutions at high order (mpmath, 30 digits).
"""

from __future__ import annotations

import math

import mpmath
import numpy as np
import pytest
import sympy as sp

import hamrkq
from hamrkq.backends.numeric import numeric_of
from hamrkq.errors import CodegenError
from hamrkq.rkq.taylor import taylor_coefficients, taylor_increment
from hamrkq.symbolic.taylor import OPCODES, tape_of, taylor_tape

x, y, t, a = sp.symbols("x y t a")


def coefficients(tape, t0, y0, params, order):
    U = np.zeros((tape.slots, order + 1))
    args = (tape.code, tape.consts, tape.setup, tape.outputs)
    taylor_coefficients(*args, t0, np.asarray(y0, float), np.asarray(params, float), order, U)
    return U[: tape.n]


def lie_series(rhs, state, point, t0, params, order):
    """Y_k = (L^k y)(point) / k!, L g = dg/dt + grad g . f, at 40 digits."""
    subs = {**dict(zip(state, point, strict=True)), t: t0, **params}
    current = list(state)
    rows = [[float(v) for v in point]]
    for k in range(1, order + 1):
        current = [
            sp.diff(g, t) + sum(sp.diff(g, s) * f for s, f in zip(state, rhs, strict=True))
            for g in current
        ]
        rows.append([float(sp.N(g.subs(subs), 40) / sp.factorial(k)) for g in current])
    return np.array(rows).T


# Every operation of the tape appears in one of these (checked below).
SYSTEMS = [
    ([y, -sp.sin(x) * (1 - y / 6) + sp.cos(x) / 3], {}),
    ([y * sp.exp(-x) + t, -(x**3) + a * x / (1 + y**2)], {a: 0.7}),
    ([sp.sqrt(1 + x**2) - sp.log(2 + y), sp.tan(x / 3) + sp.tanh(y) - sp.atan(x * y)], {}),
    (
        [
            sp.asin(x / 3) + sp.acos(y / 4) + sp.asinh(x),
            sp.acosh(2 + y**2) + sp.atanh(x / 2) + sp.sinh(x) - sp.cosh(y),
        ],
        {},
    ),
    (
        [(1 + x**2) ** sp.Rational(-3, 2) * y + a**2 * sp.cos(a), x ** (y + 3) + sp.Abs(x - 3)],
        {a: 1.3},
    ),
    ([sp.sign(y - 5) * x + 2**x, x * y / (a + t)], {a: 2.5}),
]
# Abs and sign, near the test point (x = 0.4, y = 0.3), as the smooth
# expressions they equal there, for SymPy to differentiate
NEAR_POINT = {sp.Abs(x - 3): 3 - x, sp.sign(y - 5): -1}


@pytest.mark.parametrize("case", range(len(SYSTEMS)))
def test_coefficients_equal_the_lie_series(case):
    rhs, params = SYSTEMS[case]
    tape = tape_of(rhs, [x, y], list(params), t)
    point, t0, order = (0.4, 0.3), 0.2, 5
    got = coefficients(tape, t0, point, [float(v) for v in params.values()], order)
    smooth = [f.subs(NEAR_POINT) for f in rhs]
    want = lie_series(smooth, [x, y], point, t0, params, order)
    scale = np.maximum(np.abs(want), 1e-3)
    assert np.max(np.abs(got - want) / scale) < 2e-14


def test_every_operation_is_exercised():
    seen = set()
    for rhs, params in SYSTEMS:
        seen |= set(tape_of(rhs, [x, y], list(params), t).operations())
    assert seen == set(OPCODES.values())


def test_harmonic_oscillator_to_order_30():
    # x' = y, y' = -x from (1, 0): x = cos t, coefficients (-1)^j / (2j)!
    tape = tape_of([y, -x], [x, y], [], t)
    got = coefficients(tape, 0.0, (1.0, 0.0), [], 30)
    want_x = [(-1) ** (k // 2) / math.factorial(k) if k % 2 == 0 else 0.0 for k in range(31)]
    np.testing.assert_allclose(got[0], want_x, rtol=1e-15, atol=0)


@pytest.mark.parametrize(
    ("rhs", "solution", "x0"),
    [
        (x**2, lambda s: 1 / (1 / mpmath.mpf(0.5) - s), 0.5),  # products, squares
        (sp.exp(x), lambda s: -mpmath.log(mpmath.exp(-mpmath.mpf(0.25)) - s), 0.25),
        (sp.sqrt(x), lambda s: (mpmath.sqrt(mpmath.mpf(2)) + s / 2) ** 2, 2.0),
        (x ** sp.Rational(-3, 2), lambda s: (mpmath.mpf(2) ** 2.5 + 2.5 * s) ** 0.4, 2.0),
    ],
)
def test_closed_form_solutions_to_order_25(rhs, solution, x0):
    tape = tape_of([rhs, 0 * y], [x, y], [], t)
    got = coefficients(tape, 0.0, (x0, 0.0), [], 25)[0]
    with mpmath.workdps(30):
        want = [float(c) for c in mpmath.taylor(solution, 0, 25)]
    np.testing.assert_allclose(got, want, rtol=1e-13, atol=1e-300)


@pytest.mark.parametrize("name", [p for p in hamrkq.list_problems()])
def test_catalogue_first_coefficient_is_f(name):
    problem = hamrkq.load_problem(name)
    tape = taylor_tape(problem.hamiltonian)
    numeric = numeric_of(problem.hamiltonian)
    params, y0 = problem.parameter_array, problem.y0
    got = coefficients(tape, 0.3, y0, params, 3)
    f = numeric.rhs(0.3, y0, params)
    np.testing.assert_allclose(got[:, 1], f, rtol=1e-14, atol=1e-14 * np.abs(f).max())


def test_compiled_and_interpreted_give_the_same_bits():
    numba = pytest.importorskip("numba")

    @numba.njit(error_model="numpy")
    def compiled(code, consts, setup, outputs, t0, y0, params, order, U, h, out):
        taylor_coefficients(code, consts, setup, outputs, t0, y0, params, order, U)
        taylor_increment(U, order, h, out)

    for name in ("prentice2011", "outer_solar_system", "henon_heiles"):
        problem = hamrkq.load_problem(name)
        tape = taylor_tape(problem.hamiltonian)
        results = []
        for function in (compiled, compiled.py_func):
            U = np.zeros((tape.slots, 17))
            out = np.empty(tape.n)
            args = (tape.code, tape.consts, tape.setup, tape.outputs, 0.1, problem.y0)
            function(*args, problem.parameter_array, 16, U, 0.01, out)
            results.append((U.copy(), out.copy()))
        assert np.array_equal(results[0][0], results[1][0], equal_nan=True)
        assert np.array_equal(results[0][1], results[1][1])


def test_a_step_matches_the_exact_pendulum_flow():
    # H = p^2/2 - cos q: a Taylor step of order 24 and h = 0.2 against
    # mpmath's own Taylor integrator at 30 digits
    problem = hamrkq.load_problem("pendulum")
    tape = taylor_tape(problem.hamiltonian)
    U = np.zeros((tape.slots, 25))
    out = np.empty(2)
    y0 = problem.y0
    taylor_coefficients(tape.code, tape.consts, tape.setup, tape.outputs, 0.0, y0,
                        problem.parameter_array, 24, U)  # fmt: skip
    taylor_increment(U, 24, 0.2, out)
    with mpmath.workdps(30):
        g = float(problem.parameter_array[0]) if problem.parameter_array.size else 1.0
        flow = mpmath.odefun(lambda s, v: [v[1], -g * mpmath.sin(v[0])], 0, list(y0))
        want = [float(v) for v in flow(mpmath.mpf("0.2"))]
    np.testing.assert_allclose(y0 + out, want, rtol=0, atol=4e-16)


def test_zero_leading_coefficients_give_nan_not_an_exception():
    tape = tape_of([sp.sqrt(x), sp.log(y)], [x, y], [], t)
    got = coefficients(tape, 0.0, (0.0, 0.0), [], 3)
    assert np.isnan(got[0, 2]) and np.isinf(got[1, 1])


def test_integer_powers_are_exact_through_zero():
    # x**3 by squaring: the general power's recurrence would divide by x0 = 0
    tape = tape_of([x**3 + x**5, 1 + 0 * y], [x, y], [], t)
    assert "pow" not in tape.operations()
    got = coefficients(tape, 0.0, (0.0, 0.0), [], 8)
    assert np.all(np.isfinite(got))


def test_unsupported_operation_is_refused():
    with pytest.raises(CodegenError, match="atan2"):
        tape_of([sp.atan2(x, y), y], [x, y], [], t)


def test_shared_subexpressions_and_sine_cosine_pairs():
    tape = tape_of([sp.sin(x) * sp.cos(x), sp.cos(x) + sp.sin(x) ** 2], [x, y], [], t)
    assert tape.operations()["sincos"] == 1
