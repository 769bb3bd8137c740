"""The paper's Figures 1-4 for any run or pair of runs (matplotlib, PNG).

J.S.C. Prentice, arXiv:1111.6996, Section 4 shows, for RK34Q8 against RK34:

1. :func:`figure1`: q(t) and p(t) over the first periods, the phase portrait,
   and H(t) for every run;
2. :func:`figure2`: |global error| in q and in p against t (log scale), with
   the tolerance line;
3. :func:`figure3`: the trajectory error (Euclidean, phase space) with its
   bound ``sqrt(sum_k delta_k**2)`` (``sqrt(2) delta`` in the paper's case);
4. :func:`figure4`: the estimated global error |Gamma| of the RK8 track.

Matplotlib is imported only when a figure is made, and only its
object-oriented API is used (``matplotlib.figure.Figure``, never ``pyplot``),
so nothing global changes and nothing is ever shown.  Long runs are thinned
for drawing by :func:`downsample_indices`, which keeps the smallest and the
largest value of every bin, so the maximum error is always on the plot; error
curves (log scale) are drawn as the per-bin maximum (:func:`upper_envelope`)
over a faint band of the thinned series.  For
``n > 1`` degrees of freedom, Figure 1 draws each pair ``(q_k, p_k)`` (up to
four, else the norms ``|q|`` and ``|p|``) and Figures 2 and 4 the max-norm
over the ``q``'s and over the ``p``'s, the norm the tolerance bounds.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from hamrkq.errors import InputError

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from hamrkq.analysis.diagnostics import Diagnostics
    from hamrkq.result import Solution

__all__ = [
    "downsample_indices",
    "figure1",
    "figure2",
    "figure3",
    "figure4",
    "paper_figures",
    "save_figure",
    "upper_envelope",
]

#: Points drawn per curve; a 62 000-node run is thinned to this many.
MAX_POINTS = 4000
#: Points of the phase portrait (a uniform stride through the run).
PHASE_POINTS = 20000
#: Bins of the upper envelope drawn over a long error series.
ENVELOPE_BINS = 400
#: Up to this many degrees of freedom, Figure 1 draws every pair (q_k, p_k).
MAX_PAIRS = 4
_STYLES = ({"color": "C0", "lw": 1.0}, {"color": "C3", "lw": 1.0, "ls": "--"})


# -- thinning ----------------------------------------------------------------
def downsample_indices(values: Any, max_points: int = MAX_POINTS) -> np.ndarray:
    """Indices of at most ``max_points`` (+2) samples that keep every bin's extremes.

    The series is cut into ``max_points // 2`` bins of consecutive samples and
    the positions of each bin's smallest and largest finite value are kept,
    with the first and last sample.  The global maximum and minimum are
    therefore always kept; non-finite values (nan, or zeros masked for a log
    axis) are never chosen.
    """
    values = np.asarray(values, dtype=float).reshape(-1)
    size = values.size
    if size <= max_points:
        return np.flatnonzero(np.isfinite(values)) if size else np.arange(0)
    bins = max(1, int(max_points) // 2)
    width = -(-size // bins)  # ceiling division
    padded = np.full(bins * width, np.nan)
    padded[:size] = values
    blocks = padded.reshape(bins, width)
    finite = np.isfinite(blocks)
    low = np.argmin(np.where(finite, blocks, np.inf), axis=1)
    high = np.argmax(np.where(finite, blocks, -np.inf), axis=1)
    keep = np.concatenate([low, high]) + np.tile(np.arange(bins) * width, 2)
    keep = np.unique(np.concatenate([keep[keep < size], [0, size - 1]]))
    return keep[np.isfinite(values[keep])]


def _thin(t: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    index = downsample_indices(values)
    return t[index], values[index]


def upper_envelope(
    t: Any, values: Any, bins: int = ENVELOPE_BINS
) -> tuple[np.ndarray, np.ndarray]:
    """The largest finite value of each of ``bins`` consecutive bins, and its time.

    Bins without a finite value are dropped.  The global maximum is one of
    the points returned.
    """
    t, values = np.asarray(t, dtype=float), np.asarray(values, dtype=float).reshape(-1)
    width = max(1, -(-values.size // int(bins)))
    count = -(-values.size // width)
    padded = np.full(count * width, -np.inf)
    padded[: values.size] = np.where(np.isfinite(values), values, -np.inf)
    index = np.argmax(padded.reshape(count, width), axis=1) + np.arange(count) * width
    index = index[np.isfinite(padded[index])]
    return t[index], values[index]


def _log_series(ax: Axes, t: np.ndarray, values: np.ndarray, label: str, style: dict) -> None:
    """A long error series on a log axis: the per-bin maximum as a line over a
    faint band of the thinned series, so the maximum error stands out."""
    positive = _positive(values)
    ax.plot(*_thin(t, positive), **{**style, "lw": 0.5, "alpha": 0.25})
    ax.plot(*upper_envelope(t, positive), label=label, **style)


def _positive(values: np.ndarray) -> np.ndarray:
    """|values| with zeros masked: quenched nodes have no place on a log axis."""
    out = np.abs(np.asarray(values, dtype=float))
    out[out == 0] = np.nan
    return out


# -- inputs ------------------------------------------------------------------
def _runs(runs: Any) -> list[tuple[str, Solution]]:
    """Normalise a Solution, a sequence of them or a mapping label -> Solution."""
    if isinstance(runs, Mapping):
        items = list(runs.items())
    elif isinstance(runs, Sequence) and not isinstance(runs, str):
        items = [(sol.method.upper(), sol) for sol in runs]
    else:
        items = [(runs.method.upper(), runs)]
    if not items:
        raise InputError("runs must hold at least one solution")
    return [(str(label), sol) for label, sol in items]


def _diagnostics_for(diagnostics: Any, labels: list[str]) -> dict[str, Diagnostics]:
    if diagnostics is None:
        return {}
    if isinstance(diagnostics, Mapping):
        return dict(diagnostics)
    if isinstance(diagnostics, Sequence):
        return dict(zip(labels, diagnostics, strict=True))
    return {labels[0]: diagnostics}


def _new_axes(axes: Any, count: int, figsize: tuple[float, float], layout=None):
    from matplotlib.figure import Figure

    if axes is not None:
        axes = list(np.ravel(axes))
        if len(axes) != count:
            raise InputError(f"axes must hold {count} Axes, got {len(axes)}")
        return axes[0].figure, axes
    fig = Figure(figsize=figsize, layout="constrained")
    rows, cols = layout or (count, 1)
    return fig, list(np.ravel(fig.subplots(rows, cols, squeeze=False)))


def _groups(sol: Solution) -> list[tuple[str, slice]]:
    n = sol.n
    return [("q", slice(0, n)), ("p", slice(n, 2 * n))]


def _group_label(sol: Solution, name: str) -> str:
    return name if sol.n == 1 else f"max_k |{name}_k|"


def _pair_style(style: dict, k: int, n: int) -> dict:
    """For n > 1 the pair k has its own colour; the run keeps its line style."""
    return style if n == 1 else {**style, "color": f"C{k}"}


def _first_periods(t: np.ndarray, q: np.ndarray, periods: int) -> float:
    """End of the first ``periods`` oscillations of ``q`` (upward mean crossings)."""
    centred = q - q.mean()
    ups = np.flatnonzero((centred[:-1] < 0) & (centred[1:] >= 0))
    if ups.size > periods:
        return float(t[ups[periods] + 1])
    return float(t[-1])


# -- the figures -------------------------------------------------------------
def figure1(runs: Any, *, periods: int = 3, axes: Any = None, title: str | None = None) -> Figure:
    """Figure 1: q(t), p(t) over the first periods, the phase portrait, H(t).

    Parameters
    ----------
    runs : Solution, sequence of Solution, or mapping label -> Solution
        The first run is drawn in full colour, the others dashed.
    periods : int
        How many oscillations of ``q_1`` to show in the time panels.
    axes : sequence of 4 Axes, optional
        Draw into these instead of a new figure.
    title : str, optional
        Figure title (the problem's name, say).
    """
    items = _runs(runs)
    fig, (ax_q, ax_p, ax_phase, ax_h) = _new_axes(axes, 4, (10, 7), (2, 2))
    _, first = items[0]
    end = _first_periods(first.t, first.q[:, 0], periods)
    pairs = range(min(first.n, MAX_PAIRS)) if first.n <= MAX_PAIRS else None
    for number, (label, sol) in enumerate(items):
        style = _STYLES[number % 2]
        window = sol.t <= end
        t = sol.t[window]
        for ax, part in ((ax_q, sol.q[window]), (ax_p, sol.p[window])):
            if pairs is None:
                ax.plot(t, np.linalg.norm(part, axis=1), label=label, **style)
            else:
                for k in pairs:
                    suffix = "" if sol.n == 1 else f" (k={k + 1})"
                    ax.plot(t, part[:, k], label=label + suffix, **_pair_style(style, k, sol.n))
        for k in pairs if pairs is not None else [None]:
            x = np.linalg.norm(sol.q, axis=1) if k is None else sol.q[:, k]
            y = np.linalg.norm(sol.p, axis=1) if k is None else sol.p[:, k]
            # a uniform stride keeps the orbit's order: extremes-per-bin thinning
            # would join distant points of the orbit by chords
            index = np.arange(0, x.size, max(1, -(-x.size // PHASE_POINTS)))
            suffix = "" if k is None or sol.n == 1 else f" (k={k + 1})"
            on_top = {"zorder": 3} if number == 0 else {"zorder": 2, "alpha": 0.6}
            pair = style if k is None else _pair_style(style, k, sol.n)
            ax_phase.plot(x[index], y[index], label=label + suffix, **pair, **on_top)
        tt, dh = _thin(sol.t, sol.energy - sol.energy[0])
        ax_h.plot(tt, dh, label=f"{label} (H(0) = {sol.energy[0]:.10g})", **style)
    names = ("|q|", "|p|") if pairs is None else ("q", "p") if first.n == 1 else ("q_k", "p_k")
    ax_q.set(xlabel="time t", ylabel=names[0], title=f"{names[0]}(t), first periods")
    ax_p.set(xlabel="time t", ylabel=names[1], title=f"{names[1]}(t), first periods")
    ax_phase.set(xlabel=names[0], ylabel=names[1], title="phase portrait (whole run)")
    ax_h.set(xlabel="time t", ylabel="H(t) - H(0)", title="energy error along the run")
    ax_h.ticklabel_format(axis="y", style="sci", scilimits=(-3, 3))
    for ax in (ax_q, ax_p, ax_phase, ax_h):
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize="small")
    if title:
        fig.suptitle(f"{title}: solution and Hamiltonian")
    return fig


def _error_arrays(items, diagnostics, which: str) -> list[tuple[str, Solution, np.ndarray]]:
    diags = _diagnostics_for(diagnostics, [label for label, _ in items])
    out = []
    for label, sol in items:
        diag = diags.get(label)
        if which == "estimated" and sol.global_error is not None:
            out.append((label, sol, sol.global_error))
        elif diag is not None and "error" in diag.series:
            # a run without an RK8 track (RK34) is measured against the reference
            tag = label if which == "true" else f"{label} (vs {diag.error.source} reference)"
            out.append((tag, sol, diag.series["error"]))
        else:
            raise InputError(
                f"run {label!r} has no {which} global error: pass diagnostics computed "
                "with a reference (see hamrkq.analysis.diagnostics.diagnose)"
            )
    return out


def _tolerance_line(ax, sol: Solution, part: slice, label: str) -> None:
    from hamrkq.analysis.diagnostics import tolerance

    rule = str(sol.options.get("tolerance_rule", "componentwise"))
    delta = tolerance(sol.y, sol.atol, sol.rtol, rule)[:, part].max(axis=1)
    if np.ptp(delta) == 0:
        ax.axhline(delta[0], color="k", lw=1.2, label=f"{label} = {delta[0]:.3g}")
    else:
        tt, dd = _thin(sol.t, delta)
        ax.plot(tt, dd, color="k", lw=1.2, label=label)


def figure2(
    runs: Any, *, diagnostics: Any = None, error: str = "estimated", axes: Any = None,
    title: str | None = None,
) -> Figure:  # fmt: skip
    """Figure 2: |global error| in q and in p against t, log scale, with the tolerance.

    Parameters
    ----------
    runs : Solution, sequence, or mapping label -> Solution
    diagnostics : Diagnostics, sequence or mapping label -> Diagnostics, optional
        Source of the true error (``series["error"]``), and of any run that has
        no RK8 track of its own.
    error : {"estimated", "true"}
        ``"estimated"``: the run's own ``y - z`` (the paper's way);
        ``"true"``: the error against the diagnostics' reference.
    axes : sequence of 2 Axes, optional
    title : str, optional
    """
    if error not in ("estimated", "true"):
        raise InputError(f"error must be 'estimated' or 'true', got {error!r}")
    arrays = _error_arrays(_runs(runs), diagnostics, error)
    fig, panels = _new_axes(axes, 2, (9, 6.5))
    what = "numerical minus RK8 track" if error == "estimated" else "numerical minus reference"
    for number, (label, sol, err) in enumerate(arrays):
        for ax, (name, part) in zip(panels, _groups(sol), strict=True):
            worst = np.max(np.abs(err[:, part]), axis=1)
            _log_series(ax, sol.t, worst, label, _STYLES[number % 2])
            ax.set(ylabel=f"|error in {_group_label(sol, name)}|", yscale="log")
    _, sol0, _ = arrays[0]
    for ax, (name, part) in zip(panels, _groups(sol0), strict=True):
        _tolerance_line(ax, sol0, part, "tolerance δ")
        ax.set(xlabel="time t", title=f"global error in {name} ({what})")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize="small")
    if title:
        fig.suptitle(f"{title}: global error")
    return fig


def figure3(
    runs: Any, *, diagnostics: Any = None, error: str = "estimated", ax: Axes | None = None,
    title: str | None = None,
) -> Figure:  # fmt: skip
    """Figure 3: trajectory error ``||y - y_ref||_2`` with its bound, log scale.

    The bound ``sqrt(sum_k delta_k**2)`` is ``sqrt(2) delta`` for one degree
    of freedom and an absolute tolerance (the paper's "upper bound").
    Parameters as :func:`figure2`.
    """
    from hamrkq.analysis.diagnostics import tolerance, trajectory_bound, trajectory_error

    if error not in ("estimated", "true"):
        raise InputError(f"error must be 'estimated' or 'true', got {error!r}")
    arrays = _error_arrays(_runs(runs), diagnostics, error)
    fig, (axis,) = _new_axes(None if ax is None else [ax], 1, (9, 4.5))
    for number, (label, sol, err) in enumerate(arrays):
        _log_series(axis, sol.t, trajectory_error(err), label, _STYLES[number % 2])
    _, sol0, _ = arrays[0]
    rule = str(sol0.options.get("tolerance_rule", "componentwise"))
    bound = trajectory_bound(tolerance(sol0.y, sol0.atol, sol0.rtol, rule))
    name = "√2·δ" if sol0.n == 1 else "√(Σ δ_k²)"
    if np.ptp(bound) == 0:
        axis.axhline(bound[0], color="k", lw=1.2, label=f"upper bound {name} = {bound[0]:.3g}")
    else:
        axis.plot(*_thin(sol0.t, bound), color="k", lw=1.2, label=f"upper bound {name}")
    against = "RK8 track" if error == "estimated" else "reference"
    axis.set(
        xlabel="time t", ylabel="‖y − y_ref‖₂ (phase space)", yscale="log",
        title=f"trajectory error (Euclidean, against the {against})",
    )  # fmt: skip
    axis.grid(True, which="both", alpha=0.3)
    axis.legend(fontsize="small")
    if title:
        fig.suptitle(f"{title}: trajectory error")
    return fig


def figure4(runs: Any, *, ax: Axes | None = None, title: str | None = None) -> Figure:
    """Figure 4: estimated global error |Gamma| of the RK8 track, q and p, log scale.

    Runs without a Gamma estimate are skipped; at least one must have it.
    """
    items = [(label, sol) for label, sol in _runs(runs) if sol.gamma is not None]
    if not items:
        raise InputError("no run has an estimated RK8 global error (Gamma) to plot")
    fig, (axis,) = _new_axes(None if ax is None else [ax], 1, (9, 4.5))
    for label, sol in items:
        for number, (name, part) in enumerate(_groups(sol)):
            worst = np.max(np.abs(sol.gamma[:, part]), axis=1)
            tag = f"|Γ| in {_group_label(sol, name)}" + (f" ({label})" if len(items) > 1 else "")
            _log_series(axis, sol.t, worst, tag, _STYLES[number % 2])
    axis.set(
        xlabel="time t", ylabel="|Γ| (estimated error of RK8)", yscale="log",
        title="estimated global error of the RK8 track",
    )  # fmt: skip
    axis.grid(True, which="both", alpha=0.3)
    axis.legend(fontsize="small")
    if title:
        fig.suptitle(f"{title}: RK8 error estimate")
    return fig


def paper_figures(
    runs: Any, *, diagnostics: Any = None, title: str | None = None
) -> dict[str, Figure]:
    """All four figures, keyed ``"figure1"`` .. ``"figure4"`` (Figure 4 only
    when some run has a Gamma estimate)."""
    figures = {
        "figure1": figure1(runs, title=title),
        "figure2": figure2(runs, diagnostics=diagnostics, title=title),
        "figure3": figure3(runs, diagnostics=diagnostics, title=title),
    }
    if any(sol.gamma is not None for _, sol in _runs(runs)):
        figures["figure4"] = figure4(runs, title=title)
    return figures


def save_figure(fig: Figure, path: str | os.PathLike, *, dpi: int = 120) -> Path:
    """Write ``fig`` to ``path`` atomically (a temporary file, then a rename).

    The format follows the suffix (``.png`` by default when there is none).
    A crash never leaves a half-written image under the final name.
    """
    path = Path(path)
    if not path.suffix:
        path = path.with_suffix(".png")
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as handle:
            fig.savefig(handle, format=path.suffix[1:], dpi=dpi)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path
