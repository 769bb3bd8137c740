"""The paper's Figures 1-4 for any run or pair of runs (matplotlib, PNG).

J.S.C. Prentice, arXiv:1111.6996, Section 4 shows, for RK34Q8 against RK34:

1. :func:`figure1`: q(t) and p(t) over the first periods, the phase portrait,
   and H(t) for every run;
2. :func:`figure2`: |global error| in q and in p against t (log scale), with
   the tolerance line;
3. :func:`figure3`: the trajectory error (Euclidean, phase space) with its
   bound ``sqrt(sum_k delta_k**2)`` (``sqrt(2) delta`` in the paper's case);
4. :func:`figure4`: the estimated global error |Gamma| of the quencher track
   (the paper's RK8 track; ``RK12 track`` for ``rk78q12``).

Matplotlib is imported only when a figure is made, and only its
object-oriented API is used (``matplotlib.figure.Figure``, never ``pyplot``),
so nothing global changes and nothing is ever shown.  Long runs are thinned
for drawing by :func:`downsample_indices`, which keeps the smallest and the
largest value of every bin, so the maximum error is always on the plot; error
curves (log scale) are drawn as the per-bin maximum (:func:`upper_envelope`)
over a faint band of the thinned series.  For
``n > 1`` degrees of freedom, Figure 1 draws one phase portrait per degree of
freedom (the first :data:`MAX_PAIRS`), or for N-body problems the bodies'
orbits; Figures 2 and 4 draw the max-norm over the ``q``'s and over the
``p``'s, the norm the tolerance bounds, divided by ``delta_k`` when the
tolerance differs between components or along the run.  Curves are labelled
with the problem's own coordinate names; a partial run's end is marked.

The thinning and the log-scale curves are :mod:`hamrkq.plotting.series`'s;
what the figures take and share (runs, diagnostics, axes, the ``q`` and ``p``
groups) is :mod:`hamrkq.plotting.figure_inputs`'s.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from hamrkq._files import atomic_file
from hamrkq.errors import InputError
from hamrkq.plotting.figure_inputs import diagnostics_for as _diagnostics_for
from hamrkq.plotting.figure_inputs import first_periods as _first_periods
from hamrkq.plotting.figure_inputs import group_label as _group_label
from hamrkq.plotting.figure_inputs import groups as _groups
from hamrkq.plotting.figure_inputs import labelled_runs as _runs
from hamrkq.plotting.figure_inputs import new_axes as _new_axes
from hamrkq.plotting.figure_inputs import pair_style as _pair_style
from hamrkq.plotting.figure_inputs import per_delta as _per_delta
from hamrkq.plotting.figure_inputs import tolerance_of as _delta
from hamrkq.plotting.figure_inputs import up_to as _up_to
from hamrkq.plotting.series import ENVELOPE_BINS as ENVELOPE_BINS
from hamrkq.plotting.series import MAX_POINTS as MAX_POINTS
from hamrkq.plotting.series import downsample_indices, upper_envelope
from hamrkq.plotting.series import log_series as _log_series
from hamrkq.plotting.series import thin as _thin
from hamrkq.rkq.family import track_name

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from hamrkq.result import Solution

__all__ = [
    "bodies",
    "downsample_indices",
    "figure1",
    "figure2",
    "figure3",
    "figure4",
    "paper_figures",
    "save_figure",
    "upper_envelope",
]

#: Points of the phase portrait (a uniform stride through the run).
PHASE_POINTS = 20000
#: Figure 1 draws a phase portrait for each of the first this many degrees of freedom.
MAX_PAIRS = 6
_STYLES = ({"color": "C0", "lw": 1.0}, {"color": "C3", "lw": 1.0, "ls": "--"})


# -- the figures -------------------------------------------------------------
def bodies(names: Sequence[str]) -> list[tuple[str, list[int]]] | None:
    """The bodies of an N-body problem, from its coordinate names, or None.

    Coordinates named ``x<s>``, ``y<s>`` (and ``z<s>``) for the same suffix
    ``<s>`` form body ``<s>`` (``x0, y0, z0, x1, ...`` or ``x1, y1, x2, ...``);
    returns ``[(suffix, [index of x, index of y(, index of z)]), ...]`` when
    every coordinate belongs to a body and there are at least two, else None.
    """
    groups: dict[str, dict[str, int]] = {}
    for index, name in enumerate(names):
        axis, suffix = name[:1], name[1:].lstrip("_")
        if axis not in ("x", "y", "z") or not suffix:
            return None
        groups.setdefault(suffix, {})[axis] = index
    found = []
    for suffix, axes in groups.items():
        if "x" not in axes or "y" not in axes:
            return None
        found.append((suffix, [axes[a] for a in "xyz" if a in axes]))
    return found if len(found) >= 2 else None


def _mark_partial(ax: Axes, sol: Solution) -> None:
    """A vertical line where a partial run stopped, so a short curve is not
    mistaken for a finished one."""
    if not sol.success and len(sol.t):
        ax.axvline(
            sol.t[-1], color="C3", lw=1.0, ls=":",
            label=f"{sol.method.upper()} stopped: {sol.status.name} at t = {sol.t[-1]:.6g}",
        )  # fmt: skip


def figure1(runs: Any, *, periods: int = 3, axes: Any = None, title: str | None = None) -> Figure:
    """Figure 1: the solution, its phase portraits (or orbits) and H(t).

    Three layouts, chosen from the first run:

    - N-body problems (coordinates ``x<i>, y<i>(, z<i>)``, see :func:`bodies`):
      the orbit of each body in the x-y plane, its distance from the origin
      and its momentum against t, and H(t) - H(0): four panels;
    - otherwise ``q_k(t)`` and ``p_k(t)`` over the first periods, one phase
      portrait per degree of freedom (up to :data:`MAX_PAIRS`, the first ones
      beyond), and H(t) - H(0): ``3 + min(n, MAX_PAIRS)`` panels.

    Curves and axes are labelled with the problem's own coordinate names.

    Parameters
    ----------
    runs : Solution, sequence of Solution, or mapping label -> Solution
        The first run is drawn in full colour, the others dashed.
    periods : int
        How many oscillations of the first coordinate to show in the time panels.
    axes : sequence of Axes, optional
        Draw into these instead of a new figure (as many as the layout has panels).
    title : str, optional
        Figure title (the problem's name, say).
    """
    items = _runs(runs)
    _, first = items[0]
    found = bodies(first.names[: first.n])
    if found is not None:
        fig, panels = _new_axes(axes, 4, (11, 8), (2, 2))
        _orbits(items, found, panels)
    else:
        pairs = list(range(min(first.n, MAX_PAIRS)))
        count = 3 + len(pairs)
        if axes is None and len(pairs) > 1:
            fig, panels = _phase_layout(len(pairs))
        else:
            fig, panels = _new_axes(axes, count, (10, 7), (2, 2))
        ax_q, ax_p, *phase, ax_h = panels
        _time_and_phase(items, pairs, periods, ax_q, ax_p, phase)
        if first.n > len(pairs):
            phase[0].set_title(f"{phase[0].get_title()}; first {len(pairs)} of {first.n}")
    ax_h = panels[-1]
    for number, (label, sol) in enumerate(items):
        tt, dh = _thin(sol.t, sol.energy - sol.energy[0])
        style = {**_STYLES[number % 2], **_lone(tt.size)}
        ax_h.plot(tt, dh, label=f"{label} (H(0) = {sol.energy[0]:.10g})", **style)
        _mark_partial(ax_h, sol)
    ax_h.set(xlabel="time t", ylabel="H(t) - H(0)", title="energy error along the run")
    ax_h.ticklabel_format(axis="y", style="sci", scilimits=(-3, 3))
    for ax in panels:
        ax.grid(True, alpha=0.3)
        _legend(ax, fontsize="x-small")
    if title:
        fig.suptitle(f"{title}: solution and Hamiltonian")
    return fig


def _legend(ax: Axes, **kwargs: Any) -> None:
    """The legend of what ``ax`` draws, if it draws anything labelled (an
    empty legend would be a box, and matplotlib warns)."""
    if ax.get_legend_handles_labels()[0]:
        ax.legend(**kwargs)


def _not_drawn(ax: Axes, labels: list[str]) -> None:
    """Say in the panel which series it does not draw: errors that are 0 at
    every node (a run of one node) have no place on a log axis, and no
    legend entry."""
    if labels:
        ax.text(
            0.5, 0.5, "not drawn, 0 at every node: " + ", ".join(labels),
            transform=ax.transAxes, ha="center", va="center", fontsize="small", color="0.3",
        )  # fmt: skip


def _stopped_later(ax: Axes, sol: Solution) -> None:
    """Say in a first-periods panel that the run stopped after them: the
    panel ends before the stop, which H(t) marks."""
    count = sum(text.get_text().endswith("(marked in H(t))") for text in ax.texts)
    ax.text(
        0.98, 0.03 + 0.07 * count,
        f"{sol.method.upper()} stopped later: {sol.status.name} at t = {sol.t[-1]:.6g} "
        "(marked in H(t))",
        transform=ax.transAxes, ha="right", va="bottom", fontsize="x-small", color="C3",
    )  # fmt: skip


def _lone(points: int) -> dict:
    """A marker for a curve of one point (a run with one node, t0 == t_end),
    which a line alone would not draw."""
    return {"marker": "o", "ms": 5} if points == 1 else {}


def _phase_layout(pairs: int):
    """q(t), p(t) and H on top, one phase portrait per degree of freedom below."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(max(10.0, 3.2 * pairs), 7.5), layout="constrained")
    grid = fig.add_gridspec(2, 3 * pairs)
    ax_q = fig.add_subplot(grid[0, :pairs])
    ax_p = fig.add_subplot(grid[0, pairs : 2 * pairs])
    phase = [fig.add_subplot(grid[1, 3 * k : 3 * k + 3]) for k in range(pairs)]
    ax_h = fig.add_subplot(grid[0, 2 * pairs :])
    return fig, [ax_q, ax_p, *phase, ax_h]


def _time_and_phase(items, pairs, periods, ax_q, ax_p, phase) -> None:
    _, first = items[0]
    end = _first_periods(first.t, first.q[:, 0], periods)
    # every run's window runs from its start in the first run's direction: a
    # backward run's first periods are its nodes from t0 down to end
    forward = bool(first.t[-1] >= first.t[0])
    many = len(pairs) > 1
    for number, (label, sol) in enumerate(items):
        window = _up_to(sol.t, end, forward)
        t = sol.t[window]
        style = _STYLES[number % 2]
        in_time = {**style, **_lone(t.size)}
        for ax, part, offset in ((ax_q, sol.q[window], 0), (ax_p, sol.p[window], sol.n)):
            for k in pairs:
                name = sol.names[offset + k]
                tag = f"{label}: {name}" if many else label
                ax.plot(t, part[:, k], label=tag, **_pair_style(in_time, k, len(pairs)))
            if window.size and window[-1]:
                # stopped within the first periods: the curve ends short, say why.
                _mark_partial(ax, sol)
            elif not sol.success and len(sol.t):
                # A later stop is outside this panel (marking it would stretch
                # the axis over the whole run): the panel says so, H(t) marks it.
                _stopped_later(ax, sol)
        # a uniform stride keeps the orbit's order: extremes-per-bin thinning
        # would join distant points of the orbit by chords
        index = np.arange(0, len(sol.t), max(1, -(-len(sol.t) // PHASE_POINTS)))
        on_top = {"zorder": 3} if number == 0 else {"zorder": 2, "alpha": 0.6}
        on_top |= _lone(index.size)  # not in style: it was chosen for the time window
        for ax, k in zip(phase, pairs, strict=True):
            ax.plot(sol.q[index, k], sol.p[index, k], label=label, **style, **on_top)
    names = first.names
    if many:
        ax_q.set(xlabel="time t", ylabel="coordinates", title="coordinates, first periods")
        ax_p.set(xlabel="time t", ylabel="momenta", title="momenta, first periods")
    else:
        ax_q.set(xlabel="time t", ylabel=names[0], title=f"{names[0]}(t), first periods")
        ax_p.set(
            xlabel="time t", ylabel=names[first.n], title=f"{names[first.n]}(t), first periods"
        )
    for ax, k in zip(phase, pairs, strict=False):
        q_name, p_name = names[k], names[first.n + k]
        ax.set(xlabel=q_name, ylabel=p_name, title=f"phase portrait ({q_name}, {p_name})")


def _orbits(items, found, panels) -> None:
    """N-body panels: x-y orbits, distance from the origin and |momentum| per body."""
    ax_orbit, ax_r, ax_p, _ = panels
    _, first = items[0]
    three_d = any(len(axes) == 3 for _, axes in found)
    for number, (label, sol) in enumerate(items):
        style = {**_STYLES[number % 2], **_lone(len(sol.t))}
        index = np.arange(0, len(sol.t), max(1, -(-len(sol.t) // PHASE_POINTS)))
        for k, (suffix, axes) in enumerate(found):
            body = {**style, "color": f"C{k % 10}"}
            tag = f"body {suffix}" if number == 0 else f"body {suffix} ({label})"
            ax_orbit.plot(sol.q[index, axes[0]], sol.q[index, axes[1]], label=tag, **body)
            r = np.linalg.norm(sol.q[:, axes], axis=1)
            momentum = np.linalg.norm(sol.p[:, axes], axis=1)
            ax_r.plot(*_thin(sol.t, r), label=tag, **body)
            ax_p.plot(*_thin(sol.t, momentum), label=tag, **body)
        for ax in (ax_r, ax_p):
            _mark_partial(ax, sol)
    x_name, y_name = first.names[found[0][1][0]][0], first.names[found[0][1][1]][0]
    ax_orbit.set(
        xlabel=x_name, ylabel=y_name, aspect="equal",
        title="orbits in the x-y plane" + (" (projection)" if three_d else ""),
    )  # fmt: skip
    ax_r.set(xlabel="time t", ylabel="distance from the origin", title="|position| of each body")
    ax_p.set(xlabel="time t", ylabel="|momentum|", yscale="log", title="|momentum| of each body")


def _against(arrays, prefix: str) -> str:
    """What the error curves were measured against, from where they came from
    (a fixed-step run has no quencher track even when the estimated error is
    asked)."""
    sources = {source for *_, source in arrays}
    if sources == {"reference"}:
        return f"{prefix} reference"
    tracks = _track_names(sol for _, sol, _, source in arrays if source == "rk8")
    if sources == {"rk8"}:
        return f"{prefix} {tracks}"
    return f"{prefix} {tracks} or reference, see the legend"


def _track_names(solutions) -> str:
    """The runs' quencher tracks by name (``RK8 track``, ``RK12 track``), or
    ``quencher track`` when they differ."""
    names = {track_name(sol.method) for sol in solutions}
    return names.pop() if len(names) == 1 else "quencher track"


def _error_arrays(items, diagnostics, which: str) -> list[tuple[str, Solution, np.ndarray, str]]:
    diags = _diagnostics_for(diagnostics, [label for label, _ in items])
    out = []
    for label, sol in items:
        diag = diags.get(label)
        if which == "estimated" and sol.global_error is not None:
            out.append((label, sol, sol.global_error, "rk8"))
        elif diag is not None and "error" in diag.series:
            # a run without an RK8 track (RK34) is measured against the reference
            tag = label if which == "true" else f"{label} (vs {diag.error.source} reference)"
            source = "rk8" if diag.error.source == "rk8" else "reference"
            out.append((tag, sol, diag.series["error"], source))
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
    if not np.isfinite(delta).any():
        return  # a fixed-step run has no tolerance (atol = rtol = nan): no line, no legend entry
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
    what = _against(arrays, "numerical minus")
    _, sol0, _, _ = arrays[0]
    relative = _per_delta(sol0)
    missing: list[list[str]] = [[] for _ in panels]
    for number, (label, sol, err, _) in enumerate(arrays):
        scaled = np.abs(err) / _delta(sol) if relative else np.abs(err)
        for k, (ax, (name, part)) in enumerate(zip(panels, _groups(sol), strict=True)):
            worst = np.max(scaled[:, part], axis=1)
            if not _log_series(ax, sol.t, worst, label, _STYLES[number % 2]):
                missing[k].append(label)
            group = _group_label(sol, name)
            ylabel = f"|error| / δ, {group}" if relative else f"|error in {group}|"
            ax.set(ylabel=ylabel, yscale="log")
            _mark_partial(ax, sol)
    for ax, (name, part), labels in zip(panels, _groups(sol0), missing, strict=True):
        if relative:
            ax.axhline(1.0, color="k", lw=1.2, label="tolerance: |error_k| = δ_k")
        else:
            _tolerance_line(ax, sol0, part, "tolerance δ")
        per = ", per tolerance δ_k" if relative else ""
        ax.set(xlabel="time t", title=f"global error in {name} ({what}{per})")
        ax.grid(True, which="both", alpha=0.3)
        _not_drawn(ax, labels)
        _legend(ax, fontsize="small")
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
    missing = []
    for number, (label, sol, err, _) in enumerate(arrays):
        if not _log_series(axis, sol.t, trajectory_error(err), label, _STYLES[number % 2]):
            missing.append(label)
        _mark_partial(axis, sol)
    _, sol0, _, _ = arrays[0]
    rule = str(sol0.options.get("tolerance_rule", "componentwise"))
    bound = trajectory_bound(tolerance(sol0.y, sol0.atol, sol0.rtol, rule))
    name = "√2·δ" if sol0.n == 1 else "√(Σ δ_k²)"
    # a fixed-step run has no tolerance (atol = rtol = nan): no bound, no legend entry
    if np.isfinite(bound).any() and np.ptp(bound) == 0:
        axis.axhline(bound[0], color="k", lw=1.2, label=f"upper bound {name} = {bound[0]:.3g}")
    elif np.isfinite(bound).any():
        axis.plot(*_thin(sol0.t, bound), color="k", lw=1.2, label=f"upper bound {name}")
    axis.set(
        xlabel="time t", ylabel="‖y − y_ref‖₂ (phase space)", yscale="log",
        title=f"trajectory error (Euclidean, {_against(arrays, 'against the')})",
    )  # fmt: skip
    axis.grid(True, which="both", alpha=0.3)
    _not_drawn(axis, missing)
    _legend(axis, fontsize="small")
    if title:
        fig.suptitle(f"{title}: trajectory error")
    return fig


def figure4(runs: Any, *, ax: Axes | None = None, title: str | None = None) -> Figure:
    """Figure 4: estimated global error |Gamma| of the quencher track (the
    paper's RK8 track), q and p, log scale.

    Runs without a Gamma estimate are skipped; at least one must have it.
    """
    items = [(label, sol) for label, sol in _runs(runs) if sol.gamma is not None]
    if not items:
        raise InputError("no run has an estimated quencher global error (Gamma) to plot")
    fig, (axis,) = _new_axes(None if ax is None else [ax], 1, (9, 4.5))
    relative = _per_delta(items[0][1])
    missing = []
    for label, sol in items:
        scaled = np.abs(sol.gamma) / _delta(sol) if relative else np.abs(sol.gamma)
        for number, (name, part) in enumerate(_groups(sol)):
            worst = np.max(scaled[:, part], axis=1)
            tag = f"|Γ| in {_group_label(sol, name)}" + (f" ({label})" if len(items) > 1 else "")
            if not _log_series(axis, sol.t, worst, tag, _STYLES[number % 2]):
                missing.append(tag)
        _mark_partial(axis, sol)
    _gamma_limit_line(axis, items[0][1], relative)
    track = _track_names(sol for _, sol in items)
    axis.set(
        xlabel="time t", yscale="log",
        ylabel=("|Γ| / δ" if relative else "|Γ|") + f" (estimated error of the {track})",
        title=f"estimated global error of the {track}" + (" per tolerance" if relative else ""),
    )  # fmt: skip
    axis.grid(True, which="both", alpha=0.3)
    _not_drawn(axis, missing)
    _legend(axis, fontsize="small")
    if title:
        fig.suptitle(f"{title}: error estimate of the {track}")
    return fig


def _gamma_limit_line(axis: Axes, sol: Solution, relative: bool) -> None:
    """Where the run stops with TOLERANCE_UNATTAINABLE: ``|Γ_k| > gamma_limit δ_k``
    (rounding included; see ``docs/algorithm.md``)."""
    limit = sol.options.get("gamma_limit")
    if limit is None or not np.isfinite(limit):
        return
    if relative:
        axis.axhline(limit, color="k", lw=1.0, ls="--", label=f"gamma_limit = {limit:g}")
        return
    delta = float(np.min(_delta(sol)))
    axis.axhline(
        limit * delta, color="k", lw=1.0, ls="--",
        label=f"gamma_limit · δ = {limit:g} × {delta:.3g}",
    )  # fmt: skip


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
    with atomic_file(path) as handle:
        fig.savefig(handle, format=path.suffix[1:], dpi=dpi)
    return path
