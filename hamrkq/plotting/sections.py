"""The Poincare section figure: crossings in a plane, coloured by orbit or by
its MEGNO."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from hamrkq.analysis.poincare import PoincareSection

__all__ = ["MEGNO_RANGE", "section_figure"]


#: The colour scale of an orbit's MEGNO <Y>: 0 (isochronous) to 2
#: (quasi-periodic) and beyond (chaotic, saturated at the top), as MEGNO maps
#: are drawn (REBOUND's example uses 1.9 to 4).
MEGNO_RANGE = (0.0, 5.0)


def section_figure(
    section: PoincareSection,
    x: str,
    y: str,
    *,
    ax: Any = None,
    title: str | None = None,
    megno: Any = None,
) -> Figure:
    """Scatter ``y`` against ``x`` (state component names) at every crossing,
    one colour per orbit (the classic surface of section).

    Parameters
    ----------
    section : PoincareSection
    x, y : str
        State component names for the axes.
    ax : matplotlib Axes, optional
    title : str, optional
    megno : array of one value per orbit, optional
        Colour each orbit by its MEGNO ``<Y>`` (:data:`MEGNO_RANGE`, with a
        colour bar) instead of by its index: regular and chaotic orbits apart.

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib import colormaps
    from matplotlib.colors import Normalize
    from matplotlib.figure import Figure

    if ax is None:
        fig = Figure(figsize=(6.6 if megno is not None else 6.0, 5.5), layout="constrained")
        ax = fig.add_subplot()
    else:
        fig = ax.figure
    # the orbits integrated, not the highest orbit with a crossing: an orbit
    # that never crossed (or every one, for a section out of reach) counts too
    orbits = len(section.solutions)
    if megno is not None:
        values = np.asarray(megno, dtype=float)
        if values.shape != (len(section.solutions),):
            raise ValueError(
                f"megno needs one value per orbit ({len(section.solutions)}), got shape "
                f"{values.shape}"
            )
        cmap, norm = colormaps["turbo"], Normalize(*MEGNO_RANGE)
        colours = cmap(norm(values))
    else:
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
    if megno is not None:
        from matplotlib.cm import ScalarMappable

        bar = fig.colorbar(ScalarMappable(norm=norm, cmap=cmap), ax=ax, extend="max")
        bar.set_label("orbit's MEGNO <Y> at the end (2: regular; larger: chaotic)")
    ax.set_xlabel(x)
    ax.set_ylabel(y)
    ax.set_title(title or f"Poincare section {section.section} ({_count(orbits, 'orbit')}, "
                 f"{_count(len(section.t), 'crossing')})")  # fmt: skip
    return fig


def _count(number: int, noun: str) -> str:
    return f"{number} {noun}" + ("" if number == 1 else "s")
