"""The size a state's components are measured by, and small states on floats.

:func:`component_scales` is the size each component's rounding error is
measured against (the rounding witness's rules, :mod:`hamrkq.rkq.witness_rules`,
and the shadow's limit, :mod:`hamrkq.solve.shadow`); :func:`small_state` gives a state of at
most :data:`SMALL_STATE` components and its tolerances as Python floats, on
which the rules after a run (:mod:`hamrkq.rkq.witness_rules`,
:mod:`hamrkq.rkq.auto_rules`) are cheaper than NumPy's whole-array
operations.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["SMALL_STATE", "component_scales", "scales_on_floats", "scales_per_row", "small_state"]


def component_scales(atol: np.ndarray, y0: np.ndarray) -> np.ndarray:
    """The size each component's rounding error is measured against: the
    largest ``|y0_j|`` of its half of the state (the coordinates or the
    momenta of a Hamiltonian state ``(q, p)``; the whole state when its
    length is odd), scaled by ``atol_i`` over the largest ``atol_j`` of the
    half, and at least ``|y0_i|``.

    With one ``atol`` for every component, each half is measured by its
    largest component.  Per-component floors declare the components'
    relative sizes: the outer solar system's file gives the momenta
    ``atol_i`` near ``m_i 1e-11``, from the Sun's 1e-11 to Pluto's 8e-20,
    because its momenta run from Jupiter's 5e-6 to Pluto's 2e-11.

    ``y0`` is one state, or several as the rows of a 2-D array (an
    ensemble's members), whose scales are then the rows of the result.
    """
    size = np.abs(np.asarray(y0, dtype=np.float64))
    if size.ndim == 2:
        return scales_per_row(np.asarray(atol, dtype=np.float64), size)
    small = small_state(size, atol)
    if small is not None:
        row, floor = small
        return np.array(scales_on_floats(floor, row), dtype=np.float64)
    return scales_per_row(np.asarray(atol, dtype=np.float64), size.reshape(1, -1))[0]


def scales_per_row(floor: np.ndarray, size: np.ndarray) -> np.ndarray:
    """:func:`component_scales` of each row of ``size`` (the ``|y0|`` of
    several states, shape ``(k, d)``), in whole-array operations: an
    ensemble's members at once (:func:`state_outgrew_its_start_per_row`);
    one small state has :func:`scales_on_floats`."""
    k, d = size.shape
    # One row per half of each state
    halves = 2 if d % 2 == 0 and d > 0 else 1
    size_rows = size.reshape(k, halves, -1)
    top = size_rows.max(axis=2, initial=0.0)
    if not top.all():
        # a half that is all zeros is measured by the whole state (or 1)
        whole = size.max(axis=1, initial=0.0)
        whole[whole == 0.0] = 1.0
        top = np.where(top == 0.0, whole[:, None], top)
    if floor.ndim == 0 or not d or floor.min() == floor.max():
        # One atol for every component: each share is 1, and no |y0_i|
        # exceeds its half's largest (10 us less of every call).
        return top.repeat(d // halves, axis=1)
    floor_rows = np.broadcast_to(floor, (d,)).reshape(halves, -1)
    largest = floor_rows.max(axis=1, keepdims=True, initial=0.0)
    share = np.divide(floor_rows, largest, out=np.ones_like(floor_rows), where=largest > 0.0)
    return np.maximum(size_rows, top[:, :, None] * share).reshape(k, d)


#: The most components of a state whose rules after a run
#: (:func:`state_outgrew_its_start`, :func:`needs_witness_after_run`) and
#: scales (:func:`component_scales`) are computed on Python floats: NumPy's
#: whole-array operations cost about a microsecond each whatever the size,
#: a dozen of them a rule, in a tiny problem's call of 0.3 ms (issue #13).
#: Measured side by side (one process, a loaded machine): on 2 components
#: 6 against 19 us (``state_outgrew_its_start``) and 8 against 19
#: (``needs_witness_after_run``); on 16, 11 against 14 and 14 against 12.
SMALL_STATE = 8


def small_state(*values) -> list[list[float]] | None:
    """Each of ``values`` as Python floats, one per component of a state:
    the first is the state (a 1-D float64 array of at most
    :data:`SMALL_STATE` components, not zero), each other one number or one
    per component (a tolerance, a size), as NumPy broadcasts them.  None
    where the whole-array rules decide: a longer or empty state, other
    shapes, or a value that is not finite (NaN and the infinities are
    NumPy's to propagate, as they always were)."""
    first = values[0]
    if (
        type(first) is not np.ndarray
        or first.dtype != np.float64
        or first.ndim != 1
        or not 0 < first.shape[0] <= SMALL_STATE
    ):
        return None
    d = first.shape[0]
    lists = [first.tolist()]
    for value in values[1:]:
        array = np.asarray(value, dtype=np.float64)
        if array.ndim == 0:
            lists.append([float(array)] * d)
        elif array.shape == (d,):
            lists.append(array.tolist())
        else:
            return None
    # a sum is finite only where every term is (an overflow of the sum
    # merely leaves the decision to the whole-array rules)
    if not math.isfinite(sum(map(sum, lists))):
        return None
    return lists


def scales_on_floats(floor: list[float], size: list[float]) -> list[float]:
    """:func:`component_scales` of one state's ``|y0|`` (``size``,
    non-negative finite Python floats) with the floors ``floor`` (one a
    component), on Python floats: the same values as :func:`scales_per_row` bit
    for bit (maxima, one product and one quotient a component, as there)."""
    d = len(size)
    h = d // 2 if d % 2 == 0 else d  # the length of a half (of the whole when odd)
    tops = [max(size[:h]), max(size[h:])] if h < d else [max(size)]
    if 0.0 in tops:
        # a half that is all zeros is measured by the whole state (or 1)
        whole = max(size) or 1.0
        tops = [top or whole for top in tops]
    if min(floor) == max(floor):
        # one atol for every component: each share is 1 (as scales_per_row)
        return [tops[0]] * h + [tops[-1]] * (d - h)
    scales = []
    for k, top in enumerate(tops):
        half = floor[k * h : (k + 1) * h]
        largest = max(max(half), 0.0)
        for size_i, floor_i in zip(size[k * h : (k + 1) * h], half, strict=True):
            share = floor_i / largest if largest > 0.0 else 1.0
            scales.append(max(size_i, top * share))
    return scales
