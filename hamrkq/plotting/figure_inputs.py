"""What the paper's figures take and share: runs, diagnostics, axes, the q and p groups.

:func:`labelled_runs` accepts a Solution, a sequence of them or a mapping
label -> Solution; :func:`diagnostics_for` matches diagnostics to those
labels; :func:`new_axes` makes a figure or checks the axes given.  The rest
says how a run is drawn: its ``q`` and ``p`` groups and their labels, the
tolerance it used (errors are drawn per tolerance when it varies), the
colour of each degree of freedom and the end of its first periods.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from hamrkq.errors import InputError

if TYPE_CHECKING:
    from hamrkq.analysis.diagnostics import Diagnostics
    from hamrkq.result import Solution

__all__ = [
    "diagnostics_for",
    "first_periods",
    "group_label",
    "groups",
    "labelled_runs",
    "new_axes",
    "pair_style",
    "per_delta",
    "tolerance_of",
    "up_to",
]


def labelled_runs(runs: Any) -> list[tuple[str, Solution]]:
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


def diagnostics_for(diagnostics: Any, labels: list[str]) -> dict[str, Diagnostics]:
    if diagnostics is None:
        return {}
    if isinstance(diagnostics, Mapping):
        return dict(diagnostics)
    if isinstance(diagnostics, Sequence):
        return dict(zip(labels, diagnostics, strict=True))
    return {labels[0]: diagnostics}


def new_axes(axes: Any, count: int, figsize: tuple[float, float], layout=None):
    from matplotlib.figure import Figure

    if axes is not None:
        axes = list(np.ravel(axes))
        if len(axes) != count:
            raise InputError(f"axes must hold {count} Axes, got {len(axes)}")
        return axes[0].figure, axes
    fig = Figure(figsize=figsize, layout="constrained")
    rows, cols = layout or (count, 1)
    return fig, list(np.ravel(fig.subplots(rows, cols, squeeze=False)))


def groups(sol: Solution) -> list[tuple[str, slice]]:
    n = sol.n
    return [("q", slice(0, n)), ("p", slice(n, 2 * n))]


def group_label(sol: Solution, name: str) -> str:
    """``q`` (one degree of freedom: its own name) or ``max over x, y, ...``."""
    offset = 0 if name == "q" else sol.n
    names = sol.names[offset : offset + sol.n]
    if sol.n == 1:
        return names[0]
    shown = ", ".join(names) if sol.n <= 4 else f"{names[0]}, ..., {names[-1]}"
    return f"max over {shown}"


def tolerance_of(sol: Solution) -> np.ndarray:
    from hamrkq.analysis.diagnostics import tolerance

    rule = str(sol.options.get("tolerance_rule", "componentwise"))
    return tolerance(sol.y, sol.atol, sol.rtol, rule)


def per_delta(sol: Solution) -> bool:
    """Plot errors per tolerance (``|e_k| / delta_k``) when ``delta`` differs
    between components or along the run: raw errors of components with other
    tolerances (positions in AU, momenta of 1e-11) cannot share one line."""
    return bool(np.ptp(tolerance_of(sol)) > 0)


def pair_style(style: dict, k: int, n: int) -> dict:
    """For n > 1 the pair k has its own colour; the run keeps its line style."""
    return style if n == 1 else {**style, "color": f"C{k}"}


def first_periods(t: np.ndarray, q: np.ndarray, periods: int) -> float:
    """End of the first ``periods`` oscillations of ``q`` (upward mean crossings).

    The oscillations are counted from the run's first node in the order the
    nodes were integrated, so for a backward run (``t`` decreasing) the end
    is a time below ``t[0]``; select the nodes up to it with
    :func:`up_to`, not ``t <= end``.
    """
    centred = q - q.mean()
    ups = np.flatnonzero((centred[:-1] < 0) & (centred[1:] >= 0))
    if ups.size > periods:
        return float(t[ups[periods] + 1])
    return float(t[-1])


def up_to(t: np.ndarray, end: float, forward: bool) -> np.ndarray:
    """The nodes of ``t`` integrated before reaching ``end``, as a mask.

    Parameters
    ----------
    t : ndarray
        A run's times.
    end : float
        The last time to keep (the end of the first periods, say).
    forward : bool
        True when the run goes forward in time (``t[-1] >= t[0]``); a
        backward run keeps ``t >= end``, the nodes from its start down to
        ``end``, where ``t <= end`` would keep its last periods instead.
    """
    return t <= end if forward else t >= end
