"""What a call of ``solve`` computes once and remembers: the same results as
computing it again (issue #13, the per-call overhead of a tiny problem)."""

from __future__ import annotations

import gc

import numpy as np
import pytest

import hamrkq
from hamrkq import result
from hamrkq.errors import InputError, InputTypeError
from hamrkq.options import SolveOptions
from hamrkq.rkq.driver import Integration, Settings, python_functions
from hamrkq.rkq.family import get_member
from hamrkq.rkq.layout import new_state


def test_remembered_options_are_the_options_checked_again():
    given = {"method": "rk34q8", "safety": 0.8, "keep_every": 1}
    first = SolveOptions.resolve(given, {})
    assert SolveOptions.resolve(dict(given), {}) is first
    assert first == SolveOptions._resolve(given, {})
    # equal keys of a dict, not the same option: True is no count
    with pytest.raises(InputError, match="keep_every"):
        SolveOptions.resolve({**given, "keep_every": True}, {})
    # a problem's setting under the keyword's
    assert SolveOptions.resolve({"method": "rk34q8"}, {"safety": 0.5}).safety == 0.5
    assert SolveOptions.resolve({"method": "rk34q8", "safety": 0.7}, {"safety": 0.5}).safety == 0.7


def test_an_unhashable_option_is_checked_without_the_memo():
    with pytest.raises(InputTypeError, match="safety"):
        SolveOptions.resolve({"method": "rk34q8", "safety": [0.5]}, {})


def test_auto_options_copied_once_per_member():
    options = SolveOptions.resolve({"method": "auto"}, {})
    chosen = options.with_auto(2, 1e-8)
    assert chosen.method != "auto" and chosen.z_substeps is not None
    assert options.with_auto(2, 1e-8) is chosen


@pytest.mark.parametrize("t0", [0.0, -3.5, 1e8])
def test_a_runs_state_record_is_new_states(t0):
    member = get_member("rk34q8")

    def f(t, y, params, out):
        out[:] = y

    run = Integration(
        python_functions(f, f), member, np.zeros(0), t0, np.ones(2), t0 + 1.0,
        np.full(2, 1e-6), np.zeros(2), Settings(quench=0, rule=0, gamma=0),
    )  # fmt: skip
    expected = new_state(t0)
    assert run.state.dtype == expected.dtype and run.state.shape == expected.shape
    assert run.state.tobytes() == expected.tobytes()
    assert run.state.flags.c_contiguous and run.state.flags.writeable


def test_a_dead_solutions_arrays_leave_the_registry():
    sol = hamrkq.solve(hamrkq.load_problem("harmonic"), t_span=(0.0, 0.1), method="rk34q8")
    kept = len(result._KEPT)
    ids = [id(sol.t), id(sol.y)]
    assert all(i in result._KEPT for i in ids)
    del sol
    gc.collect()
    assert len(result._KEPT) < kept
    assert not any(i in result._KEPT and result._KEPT[i]() is not None for i in ids)
