"""A Solution's arrays: its own, read-only, never shared with a caller."""

from __future__ import annotations

import numpy as np

import hamrkq


def _solution():
    return hamrkq.solve(hamrkq.load_problem("harmonic"), t_span=(0.0, 1.0), method="rk34q8")


def test_a_callers_read_only_array_is_copied_not_shared():
    # a read-only array that owns its data can be made writable again by its
    # owner: before, a Solution took it as its own (found by review)
    sol = _solution()
    mine = sol.t.copy()
    mine.setflags(write=False)
    other = sol.replace(t=mine)
    assert other.t is not mine
    mine.setflags(write=True)
    mine[0] = 99.0
    assert other.t[0] == sol.t[0]
    assert not other.t.flags.writeable


def test_replace_passes_the_solutions_own_arrays_on():
    sol = _solution()
    other = sol.replace(message="changed")
    assert other.y is sol.y and other.t is sol.t and other.z is sol.z
    assert np.array_equal(other.gamma, sol.gamma)
