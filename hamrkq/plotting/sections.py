"""The Poincare section figure: crossings in a plane, coloured by orbit."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from hamrkq.analysis.poincare import PoincareSection

__all__ = ["section_figure"]


def section_figure(
    section: PoincareSection,
    x: str,
    y: str,
    *,
    ax: Any = None,
    title: str | None = None,
) -> Figure:
    """Scatter ``y`` against ``x`` (state component names) at every crossing,
    one colour per orbit (the classic surface of section).

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib import colormaps
    from matplotlib.figure import Figure

    if ax is None:
        fig = Figure(figsize=(6.0, 5.5), layout="constrained")
        ax = fig.add_subplot()
    else:
        fig = ax.figure
    orbits = int(section.orbit.max()) + 1 if section.orbit.size else 0
    cmap = colormaps["turbo"]
    colours = cmap(np.linspace(0.0, 1.0, max(orbits, 1)))
    for k in range(orbits):
        mine = section.orbit == k
        ax.plot(
            section.column(x)[mine],
            section.column(y)[mine],
            ".",
            ms=1.5,
            color=colours[k],
            rasterized=True,
        )
    ax.set_xlabel(x)
    ax.set_ylabel(y)
    ax.set_title(title or f"Poincare section {section.section} ({orbits} orbits)")
    return fig
