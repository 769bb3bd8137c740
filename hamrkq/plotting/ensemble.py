"""Figures of an ensemble (matplotlib, object-oriented API, nothing shown).

- :func:`orbits`: every member's orbit in one ``(q_k, p_k)`` plane, coloured
  by a per-member quantity (the pendulum's phase portrait, say);
- :func:`member_map`: a per-member quantity (energy drift, the largest
  estimated global error, ...) over a one- or two-dimensional grid of
  initial values or parameters.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from hamrkq.errors import InputError

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from hamrkq.ensemble import EnsembleSolution

__all__ = ["member_map", "orbits"]


def _axes(ax: Axes | None, size: tuple[float, float]) -> tuple[Figure, Axes]:
    if ax is not None:
        return ax.figure, ax
    from matplotlib.figure import Figure

    fig = Figure(figsize=size, layout="constrained")
    return fig, fig.add_subplot()


def orbits(
    ens: EnsembleSolution,
    *,
    k: int = 0,
    color: np.ndarray | None = None,
    label: str | None = None,
    wrap: float | None = None,
    ax: Axes | None = None,
    linewidth: float = 0.6,
) -> Figure:
    """Draw each member's orbit in the ``(q_k, p_k)`` plane.

    Parameters
    ----------
    ens : EnsembleSolution
        With ``t_eval`` of at least two times.
    k : int
        Which degree of freedom.
    color : array (M,), optional
        A value per member for the colour scale, named by ``label``
        (default: ``ens.energy0``, H at each initial state).
    wrap : float, optional
        The period of an angle ``q_k`` (``2 pi`` for the pendulum): drawn in
        ``[-wrap/2, wrap/2)``, orbits broken where they wrap.
    ax : matplotlib Axes, optional
    """
    if ens.t.size < 2:
        raise InputError("orbits needs an ensemble kept at two or more times (t_eval)")
    from matplotlib import colormaps
    from matplotlib.collections import LineCollection
    from matplotlib.colors import Normalize

    fig, ax = _axes(ax, (6.4, 4.8))
    if color is None:
        color, label = ens.energy0, "H" if label is None else label
    values = np.asarray(color, dtype=float)
    finite = np.isfinite(values)
    norm = Normalize(*(np.nanmin(values[finite]), np.nanmax(values[finite])) if finite.any()
                     else (0, 1))  # fmt: skip
    qk = ens.q[:, :, k]
    if wrap is not None:
        qk = (qk + wrap / 2) % wrap - wrap / 2
    orbits_ = np.stack([qk, ens.p[:, :, k]], axis=-1)
    segments, colours = [], []
    for orbit, value in zip(orbits_, values, strict=True):
        pieces = [orbit]
        if wrap is not None:
            # One piece between wraps: no stroke across the plot.
            cuts = np.flatnonzero(np.abs(np.diff(orbit[:, 0])) > wrap / 2) + 1
            pieces = np.split(orbit, cuts)
        segments += pieces
        colours += [value] * len(pieces)
    lines = LineCollection(
        segments, array=np.array(colours), cmap=colormaps["viridis"], norm=norm,
        linewidths=linewidth,
    )  # fmt: skip
    ax.add_collection(lines)
    finite_pts = orbits_[np.isfinite(orbits_).all(axis=-1)]
    if finite_pts.size:
        ax.set_xlim(finite_pts[:, 0].min(), finite_pts[:, 0].max())
        ax.set_ylim(finite_pts[:, 1].min(), finite_pts[:, 1].max())
    ax.set_xlabel(ens.names[k])
    ax.set_ylabel(ens.names[ens.n + k])
    fig.colorbar(lines, ax=ax, label=label or "")
    ax.set_title(f"{len(ens)} orbits, t in [{ens.t[0]:g}, {ens.t[-1]:g}]")
    return fig


def member_map(
    values: np.ndarray,
    axes: Sequence[tuple[str, np.ndarray]],
    *,
    label: str,
    log: bool = False,
    ax: Axes | None = None,
) -> Figure:
    """A per-member quantity over a product grid.

    Parameters
    ----------
    values : array (M,)
        One value per member, members ordered like the grid (the first axis
        varying slowest, as ``numpy.meshgrid(..., indexing="ij")`` flattened).
    axes : sequence of (name, 1-D array)
        One or two grid axes.
    label : str
        What ``values`` is.
    log : bool
        Logarithmic colour (or y) scale; values <= 0 are drawn as missing
        (on a map, grey cells that the colour bar's label names: a member at
        an equilibrium drifts by exactly 0).
    """
    values = np.asarray(values, dtype=float)
    shape = tuple(len(a) for _, a in axes)
    if len(axes) not in (1, 2) or values.size != int(np.prod(shape)):
        raise InputError(
            f"member_map needs one or two grid axes matching {values.size} values, got {shape}"
        )
    fig, ax = _axes(ax, (6.4, 4.8))
    shown = np.where(values > 0, values, np.nan) if log else values
    if len(axes) == 1:
        ((name, x),) = axes
        ax.plot(x, shown, ".-", lw=0.8)
        ax.set_xlabel(name)
        ax.set_ylabel(label)
        if log:
            ax.set_yscale("log")
        return fig
    from matplotlib.colors import LogNorm, Normalize

    (xname, x), (yname, y) = axes
    grid = shown.reshape(shape).T  # rows: the second axis
    finite = grid[np.isfinite(grid)]
    lo, hi = (finite.min(), finite.max()) if finite.size else (1.0, 10.0)
    norm: Any = LogNorm(lo, hi) if log else Normalize(lo, hi)
    import matplotlib

    cmap = matplotlib.colormaps["magma"].with_extremes(bad="lightgrey")
    mesh = ax.pcolormesh(x, y, grid, shading="nearest", norm=norm, cmap=cmap)
    fig.colorbar(mesh, ax=ax, label=label + _missing_note(values, log))
    ax.set_xlabel(xname)
    ax.set_ylabel(yname)
    return fig


def _missing_note(values: np.ndarray, log: bool) -> str:
    """What the grey cells of a map are, for its colour bar's label: zeros
    (or negative values) that a log scale cannot show, values that are not
    finite (a failed member's), or nothing."""
    zero = bool(log and np.any(values <= 0.0))
    not_finite = bool(np.any(~np.isfinite(values)))
    if zero and not_finite:
        return " (grey: 0, or not finite)"
    if zero:
        return " (grey: 0)"
    if not_finite:
        return " (grey: not finite)"
    return ""
