"""Scalar source code generated from a Hamiltonian, cached on disk.

:func:`generate_source` turns the symbolic right-hand side, Jacobian,
Jacobian-vector product and energy of a :class:`~hamrkq.symbolic.hamiltonian.Hamiltonian`
into the text of two small Python modules of plain scalar functions, its
*parts* (:data:`PARTS`), each generated on its first use::

    # the system part: what every run calls
    rhs(t, y, params, out)        # out[:] = dy/dt
    rhs_dd(t, y, params, ylo, out, outlo, JM)  # rhs in double-double (if DD_UNSUPPORTED == "")
    energy(t, y, params) -> float # H
    energy_rows(t, Y, params, out) # out[i] = H(t[i], Y[i])

    # the tangent part: the tangent and the paper's estimates of Gamma
    jac(t, y, params, out)        # out[:, :] = d rhs / dy
    jvp(t, y, params, v, out)     # out[:] = (d rhs / dy) @ v
    rhs_jvp(t, y, params, v, out, dout, JM)  # rhs and J @ v at one point

The text is printed by SymPy's :class:`~sympy.printing.pycode.PythonCodePrinter`
(``math`` functions) from the output of :func:`sympy.cse`
(:mod:`hamrkq.backends.scalar_printer`).  Every symbol, whatever its class
(a ``Dummy`` too) or name, is printed as ``y[i]``, ``params[j]``, ``t``,
``v[k]`` or a numbered temporary (none equal to a declared symbol), and the
reason written into the module when there is no double-double form names a
function, not an expression, so no user-chosen name ever appears in the
source; the expression tree is checked against a whitelist of node types
first (:func:`check_supported`):
the compiled text comes from SymPy's printers over parsed expressions, never
from raw file text.

:func:`load_module` writes the text to the cache directory (:func:`cache_dir`)
in a file named by a hash of the inputs (:func:`cache_key`, :func:`part_key`) and imports it from
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
from collections.abc import Callable
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING

import sympy as sp

from hamrkq import _version
from hamrkq.backends.dd_printer import DD_FUNCTIONS, rhs_dd_block
from hamrkq.backends.numba_cache import CACHE_FORMAT
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
    "PARTS",
    "PART_FUNCTIONS",
    "CodegenError",
    "cache_dir",
    "cache_key",
    "check_supported",
    "double_double_unsupported",
    "generate_source",
    "is_cached",
    "load_module",
    "load_part",
    "load_source",
    "module_path",
    "part_cached",
    "part_key",
]

#: Version of the generated text's layout; part of every cache key, so a change
#: to this module's output never meets a stale file.  17: the checksum line
#: hashes the file's name too (:func:`~hamrkq.backends.source_cache.sealed`),
#: and files of 16 are not read as damaged: they are not looked up.
CODEGEN_VERSION = 17
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
    # The version read from its module each time (a dictionary lookup), not
    # bound at import.
    # numba_cache.CACHE_FORMAT: numba's files written without a checksum by
    # an earlier hamrkq are then never met (they would read as damaged).
    return (
        f"codegen={CODEGEN_VERSION};numba_cache={CACHE_FORMAT};hamrkq={_version.__version__};"
        f"{_tool_versions()};called={_called_sources_digest()}"
    )


def cache_key(ham: Hamiltonian, extra: str = "") -> str:
    """Hex digest naming the generated module of ``ham``.

    The key hashes ``srepr`` of H and of the ordered coordinates, momenta,
    parameters and time symbol (everything generated is derived from these, in
    this order), the versions of this generator, of the layout of numba's
    cache files (:data:`~hamrkq.backends.numba_cache.CACHE_FORMAT`), hamrkq,
    SymPy (which does the derivation), numba and Python, a digest of the
    sources the generated code calls (:data:`CALLED_SOURCES`), and ``extra``
    (for instance a method name).
    It does not need the derived equations, so a warm cache is found without
    differentiating anything.

    The ``srepr`` text is printed and hashed once per Hamiltonian object (a
    :class:`~hamrkq.symbolic.hamiltonian.Hamiltonian` is immutable) and the
    digest remembered for as long as the object lives; a later call looks up
    the key of that digest with the versions and ``extra`` (hashed once),
    instead of printing the expression tree.
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
    return _key_digest(expressions, _versions(), extra)


@functools.lru_cache(maxsize=256)
def _key_digest(expressions: str, versions: str, extra: str) -> str:
    # Memoised: a solve asks the key of its system three times (the backend,
    # the kernel's functions, the energy at the nodes); the versions are an
    # argument, so a changed version still changes the key.
    text = "\n".join([expressions, versions, extra])
    return hashlib.sha256(text.encode()).hexdigest()


#: The parts of a system's generated code, each a module of its own, generated
#: on first use: ``"system"`` (``rhs``, ``rhs_dd``, ``energy``,
#: ``energy_rows``: what every run calls) and ``"tangent"`` (``jac``, ``jvp``,
#: ``rhs_jvp``: called only by the tangent and the paper's estimates of Gamma,
#: by the interpreted loop's Jacobian and by SciPy's implicit methods).  For a
#: large system the tangent part is most of the generation: the symbolic
#: Jacobian and its printing (``benchmarks/lazy_functions.md``).
PARTS = ("system", "tangent")

#: The functions of each part.
PART_FUNCTIONS = {
    "system": ("rhs", "rhs_dd", "energy", "energy_rows"),
    "tangent": ("jac", "jvp", "rhs_jvp"),
}


def part_key(key: str, part: str) -> str:
    """The cache key of ``part`` (one of :data:`PARTS`) of the system whose
    key (:func:`cache_key`) is ``key``: ``key`` itself for ``"system"``, a
    hash of it for the others (so a helper process that knows only the key
    finds every part)."""
    if part not in PARTS:
        raise ValueError(f"unknown part {part!r}; valid: {', '.join(PARTS)}")
    if part == "system":
        return key
    return hashlib.sha256(f"{key}\n{part}".encode()).hexdigest()


def generate_source(ham: Hamiltonian, part: str = "system") -> str:
    """The text of the module of one part of ``ham``'s code (:data:`PARTS`).

    Parameters
    ----------
    ham : Hamiltonian
        The system; its symbolic right-hand side (and, for ``"tangent"``, its
        Jacobian) are derived here if they were not yet.
    part : {"system", "tangent"}
        ``"system"``: ``rhs``, ``rhs_dd`` (or ``DD_UNSUPPORTED``, why not),
        ``energy`` and ``energy_rows``; ``"tangent"``: ``jac``, ``jvp`` and
        ``rhs_jvp`` (which, above
        :data:`~hamrkq.backends.scalar_printer.MAX_FUSED_DIM` state
        variables, calls the system part's ``rhs``: :func:`load_module`
        binds it).

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
    if part not in PARTS:
        raise ValueError(f"unknown part {part!r}; valid: {', '.join(PARTS)}")
    dim = ham.dim
    names: dict[sp.Symbol, str] = {s: f"y[{i}]" for i, s in enumerate(ham.state)}
    names.update({s: f"params[{j}]" for j, s in enumerate(ham.parameters)})
    names[ham.t] = "t"
    parameters = frozenset(ham.parameters)
    lines = [
        '"""Generated by hamrkq.backends.codegen: do not edit (the file is rewritten when',
        f"its hash changes).  The {part} part: {', '.join(PART_FUNCTIONS[part])}.",
        "State y = (q..., p...); params ordered like Hamiltonian.parameters.",
        f'dim = {dim}, parameters = {len(ham.parameters)}."""',
        "",
        "import math",
        "",
    ]
    if part == "system":
        lines += [f"from hamrkq.rkq.ddarith import {', '.join(DD_FUNCTIONS)}", ""]
    lines += [
        f"DIM = {dim}",
        f"NPARAMS = {len(ham.parameters)}",
        f"CODEGEN_VERSION = {CODEGEN_VERSION}",
        "",
        "",
    ]
    body = _system_part if part == "system" else _tangent_part
    return "\n".join(lines + body(ham, names, parameters)) + "\n"


def _system_part(ham: Hamiltonian, names: dict, parameters: frozenset) -> list[str]:
    rhs = list(ham.rhs)
    check_supported([ham.H, *rhs], set(names))
    lines = block(
        "rhs",
        "t, y, params, out",
        "out[:] = dy/dt = (dH/dp, -dH/dq).",
        rhs,
        [f"out[{i}]" for i in range(ham.dim)],
        names,
        parameters,
    )
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
    return lines


def _tangent_part(ham: Hamiltonian, names: dict, parameters: frozenset) -> list[str]:
    dim = ham.dim
    # Equal to no declared symbol (one named _v0 would be printed as v[0]).
    numbered = sp.numbered_symbols("_v", exclude=names, real=True)
    vector = [next(numbered) for _ in range(dim)]
    names = {**names, **{s: f"v[{k}]" for k, s in enumerate(vector)}}
    rhs = list(ham.rhs)
    jac = ham.jacobian
    nonzero = [(i, j) for i in range(dim) for j in range(dim) if jac[i, j] != 0]
    products = [sp.Add(*(jac[i, j] * vector[j] for j in range(dim))) for i in range(dim)]
    check_supported(products, set(names))
    lines = block(
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
    return lines


def double_double_unsupported(ham: Hamiltonian) -> str:
    """Why ``ham``'s right-hand side has no double-double form (``rhs_dd``,
    :mod:`hamrkq.backends.dd_printer`), or ``""`` when it has one."""
    return load_module(ham).DD_UNSUPPORTED


def is_cached(ham: Hamiltonian, directory: Path | None = None, part: str = "system") -> bool:
    """True if the generated module of ``part`` of ``ham`` is on disk and
    intact (its checksum matches), so :func:`load_module` will neither
    derive nor print anything.  A caller can use it to announce a slow first
    use (generation, then compilation) before it starts."""
    return part_cached(cache_key(ham), part, directory)


def load_module(
    ham: Hamiltonian, directory: Path | None = None, part: str = "system"
) -> ModuleType:
    """The generated module of one part of ``ham``'s code, from the cache or
    freshly written (the system part first, for the tangent part).

    Parameters
    ----------
    ham : Hamiltonian
    directory : Path, optional
        Where to cache; :func:`cache_dir` by default.
    part : {"system", "tangent"}
        Which part (:data:`PARTS`).

    Returns
    -------
    module
        With the plain-Python functions of :data:`PART_FUNCTIONS` and the
        integers ``DIM`` and ``NPARAMS`` (and ``DD_UNSUPPORTED``, a string,
        in the system part).

    Raises
    ------
    CodegenError
        If the expressions cannot be printed (see :func:`check_supported`).
    OSError
        If the cache directory cannot be written.
    """
    key = cache_key(ham)
    system = load_source(key, lambda: generate_source(ham), directory)
    if part == "system":
        return system
    return load_part(key, part, lambda: generate_source(ham, part), directory)


def load_part(
    key: str,
    part: str,
    make_source: Callable[[], str] | None = None,
    directory: Path | None = None,
) -> ModuleType:
    """The module of ``part`` of the system whose key (:func:`cache_key`) is
    ``key``, from the cache or written from ``make_source()``; without
    ``make_source`` (a helper process, which has no Hamiltonian), from the
    cache only, else FileNotFoundError.  The tangent part's ``rhs_jvp``,
    which calls ``rhs`` above the fused dimension, finds the system part's.
    """
    module = load_source(part_key(key, part), make_source or _not_generated, directory)
    if part == "tangent" and not hasattr(module, "rhs"):
        module.rhs = load_source(key, _not_generated, directory).rhs
    return module


def _not_generated() -> str:
    raise FileNotFoundError("the generated module is not in the cache")


def part_cached(key: str, part: str, directory: Path | None = None) -> bool:
    """Whether ``part`` of the system whose key is ``key`` is on disk and
    intact (what :func:`is_cached` asks, for a caller that has only the key)."""
    path = module_path(part_key(key, part), directory)
    try:
        return path.exists() and damage_of(path) is None
    except OSError:
        return False
