"""Facts of double precision that several layers share.

:data:`EPS` is the machine epsilon of float64 (2**-52), and :data:`MIN_RTOL`
the smallest relative tolerance any integrator here accepts: 100 EPS, below
which the rounding of a step's arithmetic is as large as the error asked for
(SciPy's ``solve_ivp`` uses the same floor).  :func:`writable_float64` is
an array as compiled code takes it.
"""

from __future__ import annotations

import numpy as np

__all__ = ["EPS", "MIN_RTOL", "writable_float64"]

#: Machine epsilon of float64.
EPS = float(np.finfo(np.float64).eps)
#: The smallest relative tolerance: 100 eps.
MIN_RTOL = 100 * EPS


#: NPY_ARRAY_C_CONTIGUOUS | NPY_ARRAY_WRITEABLE, in ``ndarray.flags.num``.
_C_WRITEABLE = 0x0001 | 0x0400


def writable_float64(array) -> np.ndarray:
    """``np.require(array, np.float64, ("C", "W"))``: ``array`` as compiled
    signatures take it, a writable C-contiguous float64 array, copied only
    where it is not one.  The common case (every solve's parameters and every
    run's nodes are such arrays) is returned at once, without np.require's
    checks, which cost a few microseconds of a tiny problem's call."""
    if (
        type(array) is np.ndarray
        and array.dtype == np.float64
        # both flags from one flags object (each ``array.flags`` makes one)
        and array.flags.num & _C_WRITEABLE == _C_WRITEABLE
    ):
        return array
    return np.require(array, np.float64, ("C", "W"))
