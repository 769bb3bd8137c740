"""The step loop stays inside the subset of Python that numba compiles.

A later issue adds a compiled backend; this test keeps the loop honest now.
Every kernel of hamrkq.rkq is re-created over a shared namespace and
compiled with numba.njit (so that the compiled loop calls compiled kernels),
then run through the ordinary driver and compared with the Python loop.
"""

import types

import numpy as np
import pytest

from hamrkq import exact, rkq
from hamrkq.tableaus import DOP853_RK8, RK3_KUTTA, RK4_CLASSIC

numba = pytest.importorskip("numba")

pytestmark = pytest.mark.slow

KERNELS = (
    "_finite", "_combine", "_plain", "_increment", "_two_sum", "_delta", "_wnorm",
    "_rk_increment", "_rk8_tangent", "_write", "_stop", "_rk8_gamma", "_attainability",
    "initial_step", "advance",
)  # fmt: skip


@pytest.fixture(scope="module")
def compiled():
    """The kernels compiled once for the module (compilation takes ~15 s)."""
    namespace = dict(vars(rkq))
    for name in KERNELS:
        fn = getattr(rkq, name)
        clone = types.FunctionType(fn.__code__, namespace, fn.__name__, fn.__defaults__)
        namespace[name] = numba.njit(clone)
    return namespace


@numba.njit
def pendulum_rhs(t, y, params, out):
    out[0] = y[1]
    out[1] = -np.sin(y[0])


@numba.njit
def pendulum_jac(t, y, params, out):
    out[0, 0] = 0.0
    out[0, 1] = 1.0
    out[1, 0] = -np.cos(y[0])
    out[1, 1] = 0.0


def run(gamma, quench, **options):
    return rkq.run(
        pendulum_rhs, pendulum_jac, np.zeros(0), 0.0, np.array([0.0, 1.0]), 30.0,
        rk3=RK3_KUTTA, rk4=RK4_CLASSIC, rk8=DOP853_RK8, atol=np.full(2, 1e-7),
        rtol=np.zeros(2), gamma=gamma, quench=quench, inplace=True, **options,
    )  # fmt: skip


@pytest.mark.parametrize(
    ("gamma", "quench"),
    [(rkq.GAMMA_TANGENT, rkq.QUENCH_NODE), (rkq.GAMMA_PAPER, rkq.QUENCH_REDO)],
)
def test_compiled_loop_matches_the_python_loop(monkeypatch, compiled, gamma, quench):
    python = run(gamma, quench, buffer_rows=64)
    monkeypatch.setattr(rkq, "advance", compiled["advance"])
    monkeypatch.setattr(rkq, "initial_step", compiled["initial_step"])
    fast = run(gamma, quench, buffer_rows=64)
    assert fast.status == python.status == 0
    assert fast.stats == python.stats
    np.testing.assert_array_equal(fast.t, python.t)
    np.testing.assert_allclose(fast.y, python.y, rtol=0, atol=1e-14)
    np.testing.assert_allclose(fast.gamma, python.gamma, rtol=1e-6, atol=1e-20)
    assert np.abs(fast.y - exact.pendulum(fast.t, [0.0, 1.0])).max() <= 1.05e-7
