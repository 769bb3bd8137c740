"""Runge-Kutta methods as frozen, cited data, in one registry.

- :mod:`hamrkq.methods.tableaus`: :class:`ButcherTableau` (with optional
  embedded weights and FSAL), RK3, RK4, the RK3(4) pair, DOP853's 8th-order
  formula, Cooper-Verner's RK8.
- :mod:`hamrkq.methods.dormand_prince`, :mod:`~hamrkq.methods.verner`,
  :mod:`~hamrkq.methods.feagin`: the higher-order pairs and quenchers.
- :mod:`hamrkq.methods.registry`: the RKQ family by name (``PAIRS``,
  ``QUENCHERS``, ``family_members()``, ``kernel_arrays()``).
"""
