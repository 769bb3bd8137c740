"""Figures of an ensemble (Agg, object-oriented API): what is drawn is the data."""

from __future__ import annotations

import numpy as np
import pytest

import hamrkq
from hamrkq.errors import InputError
from hamrkq.plotting import ensemble as plots


@pytest.fixture(scope="module")
def rotating():
    # Rotations of the pendulum (p0 = 2.5 > 2): q grows without bound.
    return hamrkq.ensemble(
        hamrkq.load_problem("pendulum"), q0=[0.0], p0=[[2.5], [-2.5], [0.5]], t_span=(0, 8),
        t_eval=np.linspace(0, 8, 200), workers=1,
    )  # fmt: skip


def test_orbits_draws_every_member_and_colours_by_energy(rotating):
    fig = plots.orbits(rotating)
    (lines,) = fig.axes[0].collections
    assert len(lines.get_segments()) == 3
    np.testing.assert_array_equal(lines.get_array(), rotating.energy0)
    np.testing.assert_array_equal(lines.get_segments()[2][:, 0], rotating.q[2, :, 0])


def test_wrapped_orbits_stay_in_one_period_and_break_at_the_wrap(rotating):
    fig = plots.orbits(rotating, wrap=2 * np.pi)
    lines = fig.axes[0].collections[0]
    segments = lines.get_segments()
    assert len(segments) > 3  # the rotations are cut where they wrap, in one colour each
    assert set(lines.get_array()) == set(rotating.energy0)
    q = np.concatenate([s[:, 0] for s in segments])
    finite = q[np.isfinite(q)]
    assert finite.min() >= -np.pi and finite.max() < np.pi
    # q goes around more than once for p0 = +-2.5 over t = 8, yet no drawn
    # stroke crosses the plot: consecutive drawn points stay close.
    assert np.abs(rotating.q[:2, -1, 0]).min() > 2 * np.pi
    for segment in segments:
        steps = np.abs(np.diff(segment[:, 0]))
        assert np.all(steps[np.isfinite(steps)] < 0.5)


def test_member_map_draws_the_values_on_the_grid():
    x, y = np.array([0.0, 1.0, 2.0]), np.array([10.0, 20.0])
    values = np.arange(6.0) + 1  # first axis slowest: values[i * 2 + j] at (x_i, y_j)
    fig = plots.member_map(values, [("a", x), ("b", y)], label="v")
    mesh = fig.axes[0].collections[0]
    np.testing.assert_array_equal(
        np.asarray(mesh.get_array()).reshape(2, 3), [[1, 3, 5], [2, 4, 6]]
    )
    line = plots.member_map(values[:3], [("a", x)], label="v", log=True).axes[0].lines[0]
    np.testing.assert_array_equal(line.get_ydata(), values[:3])


def test_a_log_map_says_which_cells_it_cannot_show():
    """A member at an equilibrium drifts by exactly 0, which a log scale
    cannot show: its cell is grey, and the colour bar's label says so."""
    x, y = np.array([0.0, 1.0]), np.array([10.0, 20.0])
    fig = plots.member_map(np.array([1e-9, 0.0, 2e-9, 3e-9]), [("a", x), ("b", y)],
                           label="drift", log=True)  # fmt: skip
    assert fig.axes[1].get_ylabel() == "drift (grey: 0)"
    mesh = fig.axes[0].collections[0]
    assert np.ma.getmaskarray(mesh.get_array()).sum() == 1
    fig = plots.member_map(np.array([1.0, np.nan, 2.0, 3.0]), [("a", x), ("b", y)], label="v")
    assert fig.axes[1].get_ylabel() == "v (grey: not finite)"
    fig = plots.member_map(np.arange(4.0) + 1, [("a", x), ("b", y)], label="v", log=True)
    assert fig.axes[1].get_ylabel() == "v"


def test_bad_figure_requests_name_the_problem(rotating):
    with pytest.raises(InputError, match="two or more times"):
        plots.orbits(hamrkq.ensemble(hamrkq.load_problem("pendulum"), t_span=(0, 1), workers=1))
    with pytest.raises(InputError, match="matching 5 values"):
        plots.member_map(np.ones(5), [("a", np.ones(2)), ("b", np.ones(3))], label="v")
