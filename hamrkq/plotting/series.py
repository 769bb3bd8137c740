"""Long series for drawing: thinned without losing an extreme, and error curves on a log axis.

:func:`downsample_indices` keeps the smallest and the largest value of every
bin, so the maximum error is always on the plot; :func:`upper_envelope` is
the per-bin maximum; :func:`log_series` draws an error series as that
envelope over a faint band of the thinned series.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from matplotlib.axes import Axes

__all__ = [
    "ENVELOPE_BINS",
    "MAX_POINTS",
    "downsample_indices",
    "log_series",
    "thin",
    "upper_envelope",
]


#: Points drawn per curve; a 62 000-node run is thinned to this many.
MAX_POINTS = 4000
#: Bins of the upper envelope drawn over a long error series.
ENVELOPE_BINS = 400


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


def thin(t: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
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


def log_series(ax: Axes, t: np.ndarray, values: np.ndarray, label: str, style: dict) -> bool:
    """A long error series on a log axis: the per-bin maximum as a line over a
    faint band of the thinned series, so the maximum error stands out.

    Returns whether anything was drawn.  A series with no positive finite
    value (a run of one node, whose error there is 0) has no place on a log
    axis: nothing is drawn and nothing enters the legend.  A single value is
    drawn as a marked point, which a line alone would not show.
    """
    positive = _positive(values)
    envelope_t, envelope = upper_envelope(t, positive)
    if envelope.size == 0:
        return False
    ax.plot(*thin(t, positive), **{**style, "lw": 0.5, "alpha": 0.25})
    lone = {"marker": "o", "ms": 5} if envelope.size == 1 else {}
    ax.plot(envelope_t, envelope, label=label, **{**style, **lone})
    return True


def _positive(values: np.ndarray) -> np.ndarray:
    """|values| with zeros masked: quenched nodes have no place on a log axis."""
    out = np.abs(np.asarray(values, dtype=float))
    out[out == 0] = np.nan
    return out
