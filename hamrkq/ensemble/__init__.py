"""Ensembles: many initial conditions or parameter values of one system, in parallel.

:func:`ensemble` validates the request once (:mod:`hamrkq.ensemble.request`),
runs it in chunks on this machine (:mod:`hamrkq.ensemble.local`) or on a Dask
cluster (:mod:`hamrkq.ensemble.distributed`), and returns an
:class:`EnsembleSolution` (:mod:`hamrkq.ensemble.result`).
"""

from hamrkq.ensemble.api import ensemble
from hamrkq.ensemble.result import EnsembleSolution

__all__ = ["EnsembleSolution", "ensemble"]
