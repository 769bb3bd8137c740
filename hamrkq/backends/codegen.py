"""Scalar source code generated from a Hamiltonian, cached on disk.

:func:`generate_source` turns the symbolic right-hand side, Jacobian,
Jacobian-vector product and energy of a :class:`~hamrkq.symbolic.hamiltonian.Hamiltonian`
into the text of a small Python module of plain scalar functions::

    rhs(t, y, params, out)        # out[:] = dy/dt
    jac(t, y, params, out)        # out[:, :] = d rhs / dy
    jvp(t, y, params, v, out)     # out[:] = (d rhs / dy) @ v
    rhs_jvp(t, y, params, v, out, dout, JM)  # rhs and J @ v at one point
    rhs_dd(t, y, params, ylo, out, outlo, JM)  # rhs in double-double (if DD_UNSUPPORTED == "")
    energy(t, y, params) -> float # H
    energy_rows(t, Y, params, out) # out[i] = H(t[i], Y[i])

The text is printed by SymPy's :class:`~sympy.printing.pycode.PythonCodePrinter`
(``math`` functions) from the output of :func:`sympy.cse`
(:mod:`hamrkq.backends.scalar_printer`).  Every symbol is
printed as ``y[i]``, ``params[j]``, ``t``, ``v[k]`` or a numbered temporary, so
no user-chosen name ever appears in the source, and the expression tree is
checked against a whitelist of node types first (:func:`check_supported`):
the compiled text comes from SymPy's printers over parsed expressions, never
from raw file text.

:func:`load_module` writes the text to the cache directory (:func:`cache_dir`)
in a file named by a hash of the inputs (:func:`cache_key`) and imports it from
there with :mod:`importlib` (the files, their checksums and the imports are
:mod:`hamrkq.backends.source_cache`'s), so that a compiler that caches by source file
(``numba``'s ``cache=True``) can keep its machine code beside it.  The functions
are plain Python; :mod:`hamrkq.backends.compiled` compiles them.
"""

from __future__ import annotations

import functools
import hashlib
import sys
import weakref
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING

import sympy as sp

from hamrkq.backends.dd_printer import DD_FUNCTIONS, rhs_dd_block
from hamrkq.backends.scalar_printer import block, rhs_jvp_block
from hamrkq.backends.source_cache import (
    CACHE_ENV,
    CHECKSUM_PREFIX,
    MODULE_PREFIX,
    cache_dir,
    damage_of,
    load_source,
    module_path,
)
from hamrkq.errors import CodegenError
from hamrkq.symbolic.supported import check_supported

if TYPE_CHECKING:
    from hamrkq.symbolic.hamiltonian import Hamiltonian

__all__ = [
    "CACHE_ENV",
    "CHECKSUM_PREFIX",
    "CODEGEN_VERSION",
    "MODULE_PREFIX",
    "CodegenError",
    "cache_dir",
    "cache_key",
    "check_supported",
    "double_double_unsupported",
    "generate_source",
    "is_cached",
    "load_module",
    "load_source",
    "module_path",
]

#: Version of the generated text's layout; part of every cache key, so a change
#: to this module's output never meets a stale file.
CODEGEN_VERSION = 12
# cache_key's memo: one digest per Hamiltonian object, dropped with it.
_KEYS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


@functools.cache
def _tool_versions() -> str:
    # Cached: importlib.metadata scans sys.path (about 1 ms a call), and these
    # cannot change within a process.
    try:
        from importlib.metadata import version

        numba_version = version("numba")
    except Exception:  # numba absent or unreadable metadata: key on its absence
        numba_version = "none"
    return f"sympy={sp.__version__};numba={numba_version};python={sys.version_info[:2]}"


#: Sources the generated module calls into: ``rhs_dd`` calls
#: :mod:`hamrkq.rkq.ddarith`, whose code numba compiles into it.  numba's cache
#: of a function checks only that function's own file, so an edit to these
#: would load stale machine code unless the key hashes them too.
CALLED_SOURCES = (Path(__file__).resolve().parent.parent / "rkq" / "ddarith.py",)


@functools.cache
def _called_sources_digest() -> str:
    # Cached: the installed sources cannot change within a process.
    digest = hashlib.sha256()
    for path in CALLED_SOURCES:
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def _versions() -> str:
    # Read from the module each time (a dictionary lookup), not bound at import.
    from hamrkq import _version

    return (
        f"codegen={CODEGEN_VERSION};hamrkq={_version.__version__};{_tool_versions()};"
        f"called={_called_sources_digest()}"
    )


def cache_key(ham: Hamiltonian, extra: str = "") -> str:
    """Hex digest naming the generated module of ``ham``.

    The key hashes ``srepr`` of H and of the ordered coordinates, momenta,
    parameters and time symbol (everything generated is derived from these, in
    this order), the versions of this generator, hamrkq, SymPy (which does the
    derivation), numba and Python, a digest of the sources the generated code
    calls (:data:`CALLED_SOURCES`), and ``extra`` (for instance a method name).
    It does not need the derived equations, so a warm cache is found without
    differentiating anything.

    The ``srepr`` text is printed and hashed once per Hamiltonian object (a
    :class:`~hamrkq.symbolic.hamiltonian.Hamiltonian` is immutable) and the
    digest remembered for as long as the object lives; a later call hashes
    that digest with the versions and ``extra``, a few microseconds instead
    of a printing of the expression tree.
    """
    try:
        expressions = _KEYS.get(ham)
    except TypeError:  # not weak-referenceable or not hashable: no memo
        expressions = None
    if expressions is None:
        text = "\n".join(
            [
                sp.srepr(ham.H),
                sp.srepr(tuple(ham.q)),
                sp.srepr(tuple(ham.p)),
                sp.srepr(tuple(ham.parameters)),
                sp.srepr(ham.t),
            ]
        )
        expressions = hashlib.sha256(text.encode()).hexdigest()
        try:
            _KEYS[ham] = expressions
        except TypeError:
            pass
    text = "\n".join([expressions, _versions(), extra])
    return hashlib.sha256(text.encode()).hexdigest()


def generate_source(ham: Hamiltonian) -> str:
    """The text of a module defining ``rhs``, ``jac``, ``jvp``, ``rhs_jvp`` and ``energy``.

    Parameters
    ----------
    ham : Hamiltonian
        The system; its symbolic right-hand side and Jacobian are derived here
        if they were not yet.

    Returns
    -------
    str
        Python source using only ``math``, float arithmetic and item
        assignment, so that ``numba.njit`` compiles it.

    Raises
    ------
    CodegenError
        If an expression contains something the printer cannot express.
    """
    dim = ham.dim
    names: dict[sp.Symbol, str] = {s: f"y[{i}]" for i, s in enumerate(ham.state)}
    names.update({s: f"params[{j}]" for j, s in enumerate(ham.parameters)})
    names[ham.t] = "t"
    vector = sp.symbols(f"_v0:{dim}", real=True)
    names.update({s: f"v[{k}]" for k, s in enumerate(vector)})

    rhs = list(ham.rhs)
    jac = ham.jacobian
    nonzero = [(i, j) for i in range(dim) for j in range(dim) if jac[i, j] != 0]
    products = [sp.Add(*(jac[i, j] * vector[j] for j in range(dim))) for i in range(dim)]
    check_supported([ham.H, *rhs, *products], set(names))
    parameters = frozenset(ham.parameters)

    lines = [
        '"""Generated by hamrkq.backends.codegen: do not edit (the file is rewritten when',
        "its hash changes).  State y = (q..., p...); params ordered like",
        f'Hamiltonian.parameters.  dim = {dim}, parameters = {len(ham.parameters)}."""',
        "",
        "import math",
        "",
        f"from hamrkq.rkq.ddarith import {', '.join(DD_FUNCTIONS)}",
        "",
        f"DIM = {dim}",
        f"NPARAMS = {len(ham.parameters)}",
        f"CODEGEN_VERSION = {CODEGEN_VERSION}",
        "",
        "",
    ]
    lines += block(
        "rhs",
        "t, y, params, out",
        "out[:] = dy/dt = (dH/dp, -dH/dq).",
        rhs,
        [f"out[{i}]" for i in range(dim)],
        names,
        parameters,
    )
    lines += ["", ""]
    lines += block(
        "jac",
        "t, y, params, out",
        "out[:, :] = Jacobian of rhs with respect to y.",
        [jac[i, j] for i, j in nonzero],
        [f"out[{i}, {j}]" for i, j in nonzero],
        names,
        parameters,
        # Zeros first: callers reuse the output array between calls.
        prologue=["    out[:, :] = 0.0"],
    )
    lines += ["", ""]
    lines += block(
        "jvp",
        "t, y, params, v, out",
        "out[:] = Jacobian of rhs at y, times v.",
        products,
        [f"out[{i}]" for i in range(dim)],
        names,
        parameters,
    )
    lines += ["", ""]
    lines += rhs_jvp_block(rhs, jac, nonzero, dim, names, parameters)
    lines += ["", ""]
    try:
        lines += rhs_dd_block(ham)
        lines += ["", "", 'DD_UNSUPPORTED = ""']
    except CodegenError as exc:  # the double-double quencher is then refused, by name
        lines += [f"DD_UNSUPPORTED = {str(exc)!r}"]
    lines += ["", ""]
    lines += block(
        "energy", "t, y, params", "H at one state.", [ham.H], [], names, parameters, returns=True
    )
    lines += [
        "",
        "",
        "def energy_rows(t, Y, params, out):",
        '    """out[i] = H(t[i], Y[i]) for every row of Y."""',
        "    for i in range(Y.shape[0]):",
        "        out[i] = energy(t[i], Y[i], params)",
    ]
    return "\n".join(lines) + "\n"


def double_double_unsupported(ham: Hamiltonian) -> str:
    """Why ``ham``'s right-hand side has no double-double form (``rhs_dd``,
    :mod:`hamrkq.backends.dd_printer`), or ``""`` when it has one."""
    return load_module(ham).DD_UNSUPPORTED


def is_cached(ham: Hamiltonian, directory: Path | None = None) -> bool:
    """True if the generated module of ``ham`` is on disk and intact (its
    checksum matches), so :func:`load_module` will neither derive nor print
    anything.  A caller can use it to announce a slow first use (generation,
    then compilation) before it starts."""
    path = module_path(cache_key(ham), directory)
    try:
        return path.exists() and damage_of(path) is None
    except OSError:
        return False


def load_module(ham: Hamiltonian, directory: Path | None = None) -> ModuleType:
    """The generated module of ``ham``, from the cache or freshly written.

    Parameters
    ----------
    ham : Hamiltonian
    directory : Path, optional
        Where to cache; :func:`cache_dir` by default.

    Returns
    -------
    module
        With plain-Python functions ``rhs``, ``jac``, ``jvp``, ``energy``,
        ``energy_rows`` and the integers ``DIM`` and ``NPARAMS``.

    Raises
    ------
    CodegenError
        If the expressions cannot be printed (see :func:`check_supported`).
    OSError
        If the cache directory cannot be written.
    """
    return load_source(cache_key(ham), lambda: generate_source(ham), directory)
