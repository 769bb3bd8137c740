"""Runge-Kutta methods as frozen, cited data, in one registry.

- :mod:`hamrkq.methods.butcher`: :class:`ButcherTableau` (with optional
  embedded weights and FSAL) and the helpers that build its tables.
- :mod:`hamrkq.methods.tableaus`: RK3, RK4, the RK3(4) pair, Cooper-Verner's
  RK8, and DOP853's 8th-order formula and estimators (from
  :mod:`~hamrkq.methods.dop853`); :func:`~hamrkq.methods.tableaus.get_tableau`.
- :mod:`hamrkq.methods.dormand_prince`, :mod:`~hamrkq.methods.verner` (one
  module per pair, ``verner65`` ... ``verner98``), :mod:`~hamrkq.methods.feagin`
  (``feagin10``, ``feagin12``): the higher-order pairs and quenchers.
- :mod:`hamrkq.methods.registry`: the RKQ family by name (``PAIRS``,
  ``QUENCHERS``, ``family_members()``, ``kernel_arrays()``).
"""
