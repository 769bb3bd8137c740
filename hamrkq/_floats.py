"""Facts of double precision that several layers share.

:data:`EPS` is the machine epsilon of float64 (2**-52), and :data:`MIN_RTOL`
the smallest relative tolerance any integrator here accepts: 100 EPS, below
which the rounding of a step's arithmetic is as large as the error asked for
(SciPy's ``solve_ivp`` uses the same floor).
"""

from __future__ import annotations

import numpy as np

__all__ = ["EPS", "MIN_RTOL"]

#: Machine epsilon of float64.
EPS = float(np.finfo(np.float64).eps)
#: The smallest relative tolerance: 100 eps.
MIN_RTOL = 100 * EPS
