"""Dense output and events for the RKQ family: what ``solve(dense_output=,
events=)`` adds to a finished run.

- :func:`dense_output` builds :class:`hamrkq.rkq.dense.DenseOutput` (one
  quencher step from the node before ``t``) on the backend the run used.
- :func:`event_specs` turns ``events=`` into :class:`EventSpec`: SciPy-style
  callables ``g(t, y)`` (their ``terminal`` and ``direction`` attributes as in
  :func:`scipy.integrate.solve_ivp`), SymPy expressions, or strings in the
  system's own names (q's, p's, parameters, ``t``), parsed by the safe parser
  of :mod:`hamrkq.symbolic.expressions` -- never ``eval``/``sympify``.
- :func:`locate` finds every root: ``g`` on all nodes, sign changes in the
  requested direction bracketed, the roots refined on ``g(t, sol(t))`` to
  a few ulps of ``t``, every bracket at once (:func:`hamrkq.rkq.roots.bracketed_roots`);
  and the pairs of roots inside one step that node signs cannot see (an
  orbit grazing a Poincare section: ``g`` turns back between two nodes of
  the same sign), found from ``dg/dt`` at the nodes (:func:`grazing_roots`).
- :func:`apply` puts ``t_events``/``y_events``/``event_bound`` and ``sol``
  on the :class:`~hamrkq.result.Solution` and, for a terminal event, ends it
  there (``Status.TERMINAL_EVENT``).

A zero of ``g`` at the initial time is not an event (the sign must change
after ``t0``), unlike SciPy, so that an orbit started on a Poincare section
does not count its starting point.

The parts: :mod:`hamrkq.events.specs` (what ``events=`` may be, as
:class:`EventSpec`), :mod:`hamrkq.events.crossings` (where an event function
crosses zero along a dense output, and which occurrence ends a run) and
:mod:`hamrkq.events.on_solution` (a run's dense output, and the events and a
terminal stop put on its solution).  Callers use the names here.
"""

from hamrkq.events.crossings import Found, locate, locate_all, terminal_cut, terminal_watch
from hamrkq.events.on_solution import apply, dense_output
from hamrkq.events.specs import EventSpec, event_specs

__all__ = [
    "EventSpec",
    "Found",
    "apply",
    "dense_output",
    "event_specs",
    "locate",
    "locate_all",
    "terminal_cut",
    "terminal_watch",
]
