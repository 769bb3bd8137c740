"""The tolerance of each component, the one definition every layer uses.

RKQ promises that every node's error in component ``k`` is below
``delta_k = max(atol_k, rtol_k |y_k|)``; the step kernel has its own
compiled copy (:func:`hamrkq.rkq.arith.tolerance`, with the paper's rule
too).
"""

from __future__ import annotations

import numpy as np

__all__ = ["component_tolerance"]


def component_tolerance(atol, rtol, y) -> np.ndarray:
    """``delta_k = max(atol_k, rtol_k |y_k|)`` for the state (or states) ``y``;
    ``atol`` and ``rtol`` broadcast against it."""
    return np.maximum(atol, np.multiply(rtol, np.abs(y)))
