"""The paper's figures for unusual runs: backward, fixed-step, stopped, one node.

Each test reads back what a figure draws (line data, legend entries, titles)
rather than only checking that a figure is made: the defects these guard
against (found by QA) all drew a figure, just the wrong one.
"""

import warnings

import numpy as np
import pytest

from hamrkq.analysis.diagnostics import diagnose
from hamrkq.plotting.figures import figure1, figure2, figure3, figure4
from hamrkq.result import Solution, Status

pytest.importorskip("matplotlib")


def oscillation(t, **changes):
    """A harmonic oscillator's exact run at the nodes ``t`` (q = cos t, p = -sin t)."""
    t = np.asarray(t, dtype=float)
    y = np.column_stack([np.cos(t), -np.sin(t)])
    fields = dict(
        t=t, y=y, energy=np.full(t.size, 0.5), z=y.copy(), global_error=np.zeros_like(y),
        gamma=np.full_like(y, 1e-12), status=Status.SUCCESS, message="ok", method="rk34q8",
        n=1, names=("q", "p"), atol=1e-6, rtol=0.0, stats={"steps": max(t.size - 1, 0)},
    )  # fmt: skip
    fields.update(changes)
    return Solution(**fields)


def drawn_times(ax):
    """The smallest and largest t of the first curve of a time panel."""
    t = ax.lines[0].get_xydata()[:, 0]
    return t.min(), t.max()


def test_a_backward_run_shows_its_first_periods_not_its_last():
    # QA: over (0, -40) the "q(t), first periods" panel drew t in [-40, -23.9]
    forward = figure1(oscillation(np.linspace(0.0, 40.0, 4001)))
    backward = figure1(oscillation(np.linspace(0.0, -40.0, 4001)))
    low, high = drawn_times(forward.axes[0])
    assert low == 0.0 and 20.0 < high < 25.0  # three periods of 2 pi from t = 0
    for ax in backward.axes[:2]:  # q(t) and p(t)
        assert drawn_times(ax) == pytest.approx((-high, 0.0))  # from t = 0 down to -high


def legend_of(ax):
    """Each legend entry with the number of points its line draws."""
    handles, labels = ax.get_legend_handles_labels()
    return {label: len(handle.get_xydata()) for handle, label in zip(handles, labels, strict=True)}


def test_a_fixed_step_run_has_no_tolerance_line_in_its_legend():
    # QA: verlet (atol = rtol = nan) had "tolerance δ" and "upper bound √2·δ"
    # in the legends, each a line of 0 points
    run = oscillation(np.linspace(0.0, 40.0, 801), method="verlet", atol=np.full(2, np.nan),
                      rtol=np.full(2, np.nan), z=None, global_error=None, gamma=None)  # fmt: skip
    diag = diagnose(run, reference="exact", exact=lambda t: run.y - 1e-9 * t[:, None])
    for fig in (figure2(run, diagnostics=diag, error="true"), figure3(run, diagnostics=diag)):
        for ax in fig.axes:
            entries = legend_of(ax)
            assert entries and all(points > 0 for points in entries.values()), entries
            assert not any("tolerance" in label or "bound" in label for label in entries)
    # a run with a tolerance keeps both lines
    tolerant = oscillation(np.linspace(0.0, 40.0, 801), global_error=np.full((801, 2), 1e-9))
    assert "tolerance δ = 1e-06" in legend_of(figure2(tolerant).axes[0])
    assert "upper bound √2·δ = 1.41e-06" in legend_of(figure3(tolerant).axes[0])


def stop_marks(ax):
    """The times of the 'stopped' marks of a panel."""
    return [line.get_xdata()[0] for line in ax.lines if "stopped:" in line.get_label()]


def test_a_run_stopped_within_its_first_periods_is_marked_in_every_time_panel():
    # QA: a TOLERANCE_UNATTAINABLE run was marked in H(t) only, not in q(t), p(t)
    short = oscillation(np.linspace(0.0, 10.0, 501), status=Status.TOLERANCE_UNATTAINABLE,
                        message="stopped")  # fmt: skip
    fig = figure1(short)
    ax_q, ax_p, phase, ax_h = fig.axes
    for ax in (ax_q, ax_p, ax_h):
        assert stop_marks(ax) == [10.0], ax.get_title()
        assert any("stopped: TOLERANCE_UNATTAINABLE" in label for label in legend_of(ax))
    assert stop_marks(phase) == []  # no time axis
    # stopped after its first periods: q(t) and p(t) are complete and keep their
    # range; the stop is marked where the run's end is drawn, in H(t)
    late = oscillation(np.linspace(0.0, 60.0, 3001), status=Status.MAX_STEPS, message="steps")
    ax_q, ax_p, _, ax_h = figure1(late).axes
    assert stop_marks(ax_h) == [60.0]
    for ax in (ax_q, ax_p):
        assert stop_marks(ax) == [] and ax.get_xlim()[1] < 30.0
        # QA: nothing in these panels said the run had stopped; now they say
        # where, and that H(t) marks it (a text, not a legend entry: nothing
        # is drawn for it here)
        assert [text.get_text() for text in ax.texts] == [
            "RK34Q8 stopped later: MAX_STEPS at t = 60 (marked in H(t))"
        ]
    assert not ax_h.texts and not figure1(oscillation(np.linspace(0, 60, 3001))).axes[0].texts


def test_a_one_node_run_has_no_legend_entry_for_an_error_curve_it_cannot_draw():
    # QA: t_span (0, 0) gave Figures 2 and 4 (and 3) a legend entry for each
    # error curve, a line of 0 points: the error at the only node is 0, which
    # a log axis cannot show
    one = oscillation([0.0], gamma=np.zeros((1, 2)))
    diag = diagnose(one, reference="exact", exact=lambda t: one.y)
    figures = {
        "figure2": figure2(one),
        "figure2 true": figure2(one, diagnostics=diag, error="true"),
        "figure3": figure3(one, diagnostics=diag),
        "figure4": figure4(one),
    }
    for name, fig in figures.items():
        for ax in fig.axes:
            entries = legend_of(ax)
            assert all(points > 0 for points in entries.values()), (name, entries)
            assert not any("RK34Q8" in label or "Γ" in label for label in entries), name
            (text,) = [text.get_text() for text in ax.texts]
            assert text.startswith("not drawn, 0 at every node: "), name
    assert figures["figure4"].axes[0].texts[0].get_text().endswith("|Γ| in q, |Γ| in p")
    assert list(legend_of(figures["figure2"].axes[0])) == ["tolerance δ = 1e-06"]
    # no curve and no other line: no legend at all (not an empty box, nor
    # matplotlib's warning about one)
    bare = oscillation([0.0], gamma=np.zeros((1, 2)), options={"gamma_limit": np.inf})
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert figure4(bare).axes[0].get_legend() is None
    # an error that is not 0 at the one node is drawn, as a marked point
    off = oscillation([0.0], global_error=np.full((1, 2), 1e-9))
    ax = figure2(off).axes[0]
    (curve,) = [line for line in ax.lines if line.get_label() == "RK34Q8"]
    assert curve.get_xydata().tolist() == [[0.0, 1e-9]] and curve.get_marker() == "o"
    assert not ax.texts


def test_the_section_title_counts_the_orbits_integrated_and_the_crossings():
    from hamrkq.analysis.poincare import PoincareSection
    from hamrkq.plotting.sections import section_figure

    names = ("q1", "q2", "p1", "p2")
    runs = [oscillation(np.linspace(0.0, 5.0, 11)) for _ in range(3)]

    def section(orbit, solutions):
        orbit = np.asarray(orbit, dtype=int)
        y = np.arange(4.0 * orbit.size).reshape(-1, 4)
        return PoincareSection(t=np.arange(orbit.size, dtype=float), y=y, orbit=orbit,
                               section="q1 = 5", names=names, solutions=solutions)  # fmt: skip

    # QA: one orbit integrated, no crossing, was titled "(0 orbits)"
    ax = section_figure(section([], runs[:1]), "q2", "p2").axes[0]
    assert ax.get_title() == "Poincare section q1 = 5 (1 orbit, 0 crossings)"
    # three orbits, the last one never crossing: not "(2 orbits)"
    sec = section([0, 1, 0, 1, 1], runs)
    ax = section_figure(sec, "q2", "p2").axes[0]
    assert ax.get_title() == "Poincare section q1 = 5 (3 orbits, 5 crossings)"
    for k, line in enumerate(ax.lines):  # line k draws orbit k's crossings
        mine = sec.orbit == k
        np.testing.assert_array_equal(line.get_xydata(), sec.y[mine][:, [1, 3]])


@pytest.mark.parametrize("layout", ["one dof", "n-body"])
def test_a_one_node_run_is_drawn_as_a_marked_point(layout):
    # QA: t_span (0, 0) drew in every panel a 1-point line without a marker
    # (nothing visible), each with a legend entry
    if layout == "one dof":
        one = oscillation([0.0])
    else:  # x1, y1, x2, y2: two bodies, Figure 1's orbit layout
        names = ("x1", "y1", "x2", "y2", "px1", "py1", "px2", "py2")
        y = np.array([[1.0, 0.0, 2.0, 0.0, 0.0, 1.0, 0.0, 0.5]])
        one = oscillation([0.0], y=y, z=y, global_error=0 * y, gamma=0 * y, n=4, names=names)
    fig = figure1(one)
    for ax in fig.axes:
        for handle, label in zip(*ax.get_legend_handles_labels(), strict=True):
            assert len(handle.get_xydata()) == 1, (ax.get_title(), label)
            assert handle.get_marker() not in ("None", "", " ", None), (ax.get_title(), label)
    # the first panel's point: (t, q) = (0, 1), or body 1 at (x1, y1) = (1, 0)
    np.testing.assert_array_equal(fig.axes[0].lines[0].get_xydata(), [[0.0, 1.0]]
                                  if layout == "one dof" else [[1.0, 0.0]])  # fmt: skip
    # a run of many nodes keeps plain lines
    many = figure1(oscillation(np.linspace(0.0, 10.0, 101)))
    assert all(line.get_marker() == "None" for ax in many.axes for line in ax.lines)
