"""The paper's figures under Agg (hamrkq.plotting.figures)."""

import numpy as np
import pytest

from hamrkq.analysis.diagnostics import diagnose
from hamrkq.errors import InputError
from hamrkq.plotting.figures import (
    downsample_indices,
    figure1,
    figure2,
    figure3,
    figure4,
    paper_figures,
    save_figure,
    upper_envelope,
)
from hamrkq.result import Solution, Status

matplotlib = pytest.importorskip("matplotlib")
from matplotlib.figure import Figure  # noqa: E402
from matplotlib.image import imread  # noqa: E402


def run(n=1, nodes=30001, method="rk34q8", track=True, spike_at=None):
    """A synthetic oscillating run with a known error (and a spike to find)."""
    t = np.linspace(0.0, 300.0, nodes)
    phases = np.arange(1, n + 1)[None, :]
    q = np.sin(t[:, None] * phases)
    p = np.cos(t[:, None] * phases)
    error = 5e-7 * np.abs(np.sin(7 * t))[:, None] * np.ones((1, 2 * n))
    if spike_at is not None:
        error[spike_at] = 9e-7
    y = np.hstack([q, p])
    z = y - error if track else None
    names = ("q", "p") if n == 1 else tuple(f"{s}{k}" for s in "qp" for k in range(1, n + 1))
    return Solution(
        t=t, y=y, energy=0.5 + 1e-8 * np.sin(t), z=z,
        global_error=None if z is None else y - z,
        gamma=np.full_like(y, 1e-11) * (1 + t[:, None]) if track else None,
        status=Status.SUCCESS, message="ok", method=method, n=n, names=names,
        atol=1e-6, rtol=0.0, stats={"steps": nodes - 1},
    )  # fmt: skip


def not_blank(path):
    pixels = imread(str(path))
    return pixels.ndim == 3 and float(np.var(pixels[..., :3])) > 0


def test_downsampling_keeps_the_extremes():
    rng = np.random.default_rng(0)
    values = rng.standard_normal(100_003)
    values[54_321] = 50.0
    values[777] = -40.0
    index = downsample_indices(values, max_points=1000)
    assert index.size <= 1002
    assert 54_321 in index and 777 in index
    assert index[0] == 0 and index[-1] == values.size - 1
    assert np.all(np.diff(index) > 0)
    values[10:20] = np.nan  # nan (masked zeros on a log axis) is never chosen
    assert np.all(np.isfinite(values[downsample_indices(values, 1000)]))
    assert downsample_indices(np.array([1.0, np.nan, 2.0])).tolist() == [0, 2]


def test_upper_envelope_contains_the_maximum():
    t = np.linspace(0, 1, 10_001)
    values = np.sin(40 * t) ** 2
    values[6_789] = 3.0
    tt, vv = upper_envelope(t, values, bins=100)
    assert vv.max() == 3.0 and tt[np.argmax(vv)] == t[6_789]
    assert vv.size == 100


def test_figure2_shows_the_largest_error(tmp_path):
    sol = run(spike_at=12_345)
    fig = figure2(sol)
    assert isinstance(fig, Figure) and len(fig.axes) == 2
    drawn = [line.get_ydata() for line in fig.axes[0].lines if line.get_label() == "RK34Q8"]
    assert np.nanmax(drawn[0]) == pytest.approx(9e-7)  # the spike survives the thinning
    labels = [line.get_label() for line in fig.axes[0].lines]
    assert "RK34Q8" in labels and any(label.startswith("tolerance δ") for label in labels)
    assert fig.axes[0].get_yscale() == "log"
    assert not_blank(save_figure(fig, tmp_path / "figure2.png"))


def test_all_four_figures_for_a_pair_of_runs(tmp_path):
    rkq, rk34 = run(), run(method="rk34", track=False)
    diags = {"RK34Q8": diagnose(rkq, reference="rk8"), "RK34": None}
    diags["RK34"] = diagnose(rk34, reference="exact", exact=lambda t: rk34.y - 1e-3 * t[:, None])
    figures = paper_figures({"RK34Q8": rkq, "RK34": rk34}, diagnostics=diags, title="synthetic")
    assert sorted(figures) == ["figure1", "figure2", "figure3", "figure4"]
    for name, fig in figures.items():
        path = save_figure(fig, tmp_path / name)
        assert path.suffix == ".png" and path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert not_blank(path)
    assert len(figures["figure1"].axes) == 4
    # RK34 has no RK8 track: its error comes from the diagnostics, and says so
    labels = [line.get_label() for line in figures["figure2"].axes[0].lines]
    assert any("RK34 (vs exact reference)" in label for label in labels)
    bound = [
        line for line in figures["figure3"].axes[0].lines if "upper bound" in line.get_label()
    ]
    assert bound and "√2·δ" in bound[0].get_label()
    assert bound[0].get_ydata()[0] == pytest.approx(np.sqrt(2) * 1e-6)
    assert list(tmp_path.glob("*.tmp")) == []


@pytest.mark.parametrize("n", [2, 6])
def test_more_degrees_of_freedom(n, tmp_path):
    sol = run(n=n, nodes=3001)
    fig1 = figure1(sol)
    assert len(fig1.axes) == 3 + n  # q(t), p(t), H, and one phase portrait per dof
    assert len(fig1.axes[0].lines) == n  # one curve per coordinate, by its name
    assert [line.get_label() for line in fig1.axes[0].lines][:2] == ["RK34Q8: q1", "RK34Q8: q2"]
    titles = [ax.get_title() for ax in fig1.axes[2:-1]]
    assert titles[0] == "phase portrait (q1, p1)" and titles[-1] == f"phase portrait (q{n}, p{n})"
    q1, p1 = fig1.axes[2].lines[0].get_data()
    np.testing.assert_array_equal(q1, sol.q[: q1.size, 0])  # q1 against p1, uniform stride
    np.testing.assert_array_equal(p1, sol.p[: p1.size, 0])
    fig2 = figure2(sol)
    assert "max over q1, " in fig2.axes[0].get_ylabel()
    for fig in (fig1, fig2, figure3(sol), figure4(sol)):
        assert not_blank(save_figure(fig, tmp_path / "f.png"))


def nbody(dims=2, bodies=3, nodes=2001, **changes):
    """Circular orbits of radius k about the origin, names x1, y1(, z1), ..."""
    t = np.linspace(0.0, 20.0, nodes)
    q, p, names = [], [], []
    for k in range(1, bodies + 1):
        q += [k * np.cos(t / k), k * np.sin(t / k)] + ([0 * t] if dims == 3 else [])
        p += [-np.sin(t / k), np.cos(t / k)] + ([0 * t] if dims == 3 else [])
        names += [f"{a}{k}" for a in "xyz"[:dims]]
    y = np.column_stack(q + p)
    names += [f"p{name}" for name in names]
    fields = dict(
        t=t, y=y, energy=np.ones_like(t), z=y - 1e-9, global_error=np.full_like(y, 1e-9),
        gamma=np.full_like(y, 1e-12), status=Status.SUCCESS, message="ok", method="rk34q8",
        n=dims * bodies, names=tuple(names), atol=1e-6, rtol=0.0, stats={"steps": nodes - 1},
    )  # fmt: skip
    fields.update(changes)
    return Solution(**fields)


@pytest.mark.parametrize("dims", [2, 3])
def test_nbody_figure1_draws_orbits(dims, tmp_path):
    from hamrkq.plotting.figures import bodies

    sol = nbody(dims)
    assert [b for b, _ in bodies(sol.names[: sol.n])] == ["1", "2", "3"]
    assert bodies(["q1", "q2"]) is None and bodies(["x1", "x2"]) is None
    fig = figure1(sol)
    orbit = fig.axes[0]
    assert orbit.get_xlabel() == "x" and orbit.get_ylabel() == "y"
    assert [line.get_label() for line in orbit.lines] == ["body 1", "body 2", "body 3"]
    for k, line in enumerate(orbit.lines, start=1):
        x, y = line.get_data()
        np.testing.assert_allclose(np.hypot(x, y), k)  # each orbit is the body's circle
    radius = fig.axes[1].lines[2].get_ydata()
    np.testing.assert_allclose(radius, 3.0)
    assert not_blank(save_figure(fig, tmp_path / "f.png"))


def test_errors_per_tolerance_and_gamma_limit_when_delta_differs():
    # momenta with a tolerance 1e4 times tighter than the positions (as in the
    # outer solar system): the raw errors would hide the momenta's
    sol = nbody(atol=np.array([1e-6] * 6 + [1e-10] * 6), options={"gamma_limit": 0.05})
    fig2 = figure2(sol)
    drawn = next(line for line in fig2.axes[1].lines if line.get_label() == "RK34Q8")
    assert np.nanmax(drawn.get_ydata()) == pytest.approx(1e-9 / 1e-10)
    assert "per tolerance" in fig2.axes[1].get_title()
    assert "|error| / δ, max over px1, " in fig2.axes[1].get_ylabel()
    one = [line for line in fig2.axes[0].lines if "tolerance" in line.get_label()]
    assert one[0].get_ydata()[0] == 1.0
    fig4 = figure4(sol)
    limit = [line for line in fig4.axes[0].lines if "gamma_limit" in line.get_label()]
    assert limit and limit[0].get_ydata()[0] == 0.05
    # a uniform tolerance keeps the paper's raw errors, the limit as gamma_limit * delta
    plain = run().replace(options={"gamma_limit": 0.05})
    limit = [line for line in figure4(plain).axes[0].lines if "gamma_limit" in line.get_label()]
    assert limit[0].get_ydata()[0] == pytest.approx(0.05 * 1e-6)


def test_partial_run_is_marked_and_titles_say_what_the_error_is_against():
    partial = run(nodes=3001).replace(status=Status.MAX_STEPS, message="step limit")
    for fig in (figure1(partial), figure2(partial), figure3(partial), figure4(partial)):
        marks = [
            line
            for ax in fig.axes
            for line in ax.lines
            if "stopped: MAX_STEPS" in line.get_label()
        ]
        assert marks and marks[0].get_xdata()[0] == partial.t[-1]
    # a fixed-step run has no RK8 track: its "estimated" figure is against the reference
    gauss = run(method="gauss4", track=False)
    diag = diagnose(gauss, reference="exact", exact=lambda t: gauss.y - 1e-9 * t[:, None])
    fig = figure2(gauss, diagnostics=diag)
    assert all("RK8" not in ax.get_title() for ax in fig.axes)
    assert "numerical minus reference" in fig.axes[0].get_title()
    assert "RK8" not in figure3(gauss, diagnostics=diag).axes[0].get_title()


def test_true_error_needs_diagnostics_and_gamma_is_required_for_figure4():
    rk34 = run(method="rk34", track=False)
    with pytest.raises(InputError, match="no estimated global error"):
        figure2(rk34)
    with pytest.raises(InputError, match="no true global error"):
        figure3(run(), error="true")
    with pytest.raises(InputError, match="Gamma"):
        figure4(rk34)
    with pytest.raises(InputError, match="error must be"):
        figure2(run(), error="paper")


def test_drawing_into_given_axes():
    from matplotlib.figure import Figure

    host = Figure()
    ax = host.subplots()
    assert figure3(run(nodes=501), ax=ax) is host
    grid = Figure().subplots(2, 2)
    assert figure1(run(nodes=501), axes=grid) is grid[0, 0].figure
    with pytest.raises(InputError, match="4 Axes"):
        figure1(run(nodes=501), axes=[ax])


def test_save_figure_is_atomic_on_failure(tmp_path):
    fig = figure4(run(nodes=501))
    with pytest.raises(ValueError, match="xyz"):
        save_figure(fig, tmp_path / "bad.xyz")
    assert list(tmp_path.iterdir()) == []
