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
    q_lines = [line for line in fig1.axes[0].lines]
    assert len(q_lines) == (n if n <= 4 else 1)  # one per pair, else the norm |q|
    fig2 = figure2(sol)
    assert "max_k |q_k|" in fig2.axes[0].get_ylabel()
    for fig in (fig1, fig2, figure3(sol), figure4(sol)):
        assert not_blank(save_figure(fig, tmp_path / "f.png"))


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
