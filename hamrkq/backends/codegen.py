"""Scalar source code generated from a Hamiltonian, cached on disk.

:func:`generate_source` turns the symbolic right-hand side, Jacobian,
Jacobian-vector product and energy of a :class:`~hamrkq.symbolic.hamiltonian.Hamiltonian`
into the text of a small Python module of plain scalar functions::

    rhs(t, y, params, out)        # out[:] = dy/dt
    jac(t, y, params, out)        # out[:, :] = d rhs / dy
    jvp(t, y, params, v, out)     # out[:] = (d rhs / dy) @ v
    rhs_jvp(t, y, params, v, out, dout, JM)  # rhs and J @ v at one point
    energy(t, y, params) -> float # H
    energy_rows(t, Y, params, out) # out[i] = H(t[i], Y[i])

The text is printed by SymPy's :class:`~sympy.printing.pycode.PythonCodePrinter`
(``math`` functions) from the output of :func:`sympy.cse`.  Every symbol is
printed as ``y[i]``, ``params[j]``, ``t``, ``v[k]`` or a numbered temporary, so
no user-chosen name ever appears in the source, and the expression tree is
checked against a whitelist of node types first (:func:`check_supported`):
the compiled text comes from SymPy's printers over parsed expressions, never
from raw file text.

:func:`load_module` writes the text to the cache directory (:func:`cache_dir`)
in a file named by a hash of the inputs (:func:`cache_key`) and imports it from
there with :mod:`importlib`, so that a compiler that caches by source file
(``numba``'s ``cache=True``) can keep its machine code beside it.  The functions
are plain Python; :mod:`hamrkq.backends.compiled` compiles them.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.util
import os
import sys
import threading
import warnings
import weakref
from collections.abc import Sequence
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING

import sympy as sp
from sympy.printing.precedence import PRECEDENCE
from sympy.printing.pycode import PythonCodePrinter

from hamrkq._files import atomic_file
from hamrkq.errors import CodegenError, HamrkqWarning
from hamrkq.symbolic.supported import check_supported

if TYPE_CHECKING:
    from hamrkq.symbolic.hamiltonian import Hamiltonian

__all__ = [
    "CACHE_ENV",
    "CODEGEN_VERSION",
    "CodegenError",
    "cache_dir",
    "cache_key",
    "check_supported",
    "generate_source",
    "is_cached",
    "load_module",
    "module_path",
]

#: Environment variable that overrides the cache directory.
CACHE_ENV = "HAMRKQ_CACHE_DIR"
#: Version of the generated text's layout; part of every cache key, so a change
#: to this module's output never meets a stale file.
CODEGEN_VERSION = 9
#: Integer powers up to this are printed as products (see _ScalarPrinter).
MAX_PRODUCT_POWER = 4
#: Largest dimension for which rhs_jvp repeats the bodies of rhs and jac
#: (fused); above it rhs_jvp calls them (numba's compile time grows with the
#: length of a function: outer_solar_system's fused rhs_jvp took 13 s more).
MAX_FUSED_DIM = 12
#: Prefix of generated module names (``sys.modules`` keys and file stems).
MODULE_PREFIX = "hamrkq_gen_"

_MODULE_LOCK = threading.Lock()
_LOADED: dict[str, ModuleType] = {}
# cache_key's memo: one digest per Hamiltonian object, dropped with it.
_KEYS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
#: The last line of every cached file: ``CHECKSUM_PREFIX`` + the SHA-256 of
#: the text before it.  A file whose last line does not match (truncated,
#: emptied, edited) is rebuilt, not imported.
CHECKSUM_PREFIX = "# hamrkq-checksum: sha256="


def cache_dir() -> Path:
    """The directory that holds generated modules and their compiled code.

    ``$HAMRKQ_CACHE_DIR`` if set; otherwise the platform's per-user cache
    directory: ``$XDG_CACHE_HOME/hamrkq`` or ``~/.cache/hamrkq`` on Linux and
    other Unix systems, ``~/Library/Caches/hamrkq`` on macOS,
    ``%LOCALAPPDATA%\\hamrkq\\Cache`` on Windows.  The directory is not created
    here.
    """
    override = os.environ.get(CACHE_ENV)
    if override:
        return Path(override).expanduser()
    if sys.platform == "win32":
        base = os.environ.get("LOCALAPPDATA") or str(Path.home() / "AppData" / "Local")
        return Path(base) / "hamrkq" / "Cache"
    if sys.platform == "darwin":
        return Path.home() / "Library" / "Caches" / "hamrkq"
    base = os.environ.get("XDG_CACHE_HOME")
    # The XDG spec says a relative XDG_CACHE_HOME is invalid and must be ignored.
    if not base or not os.path.isabs(base):
        base = str(Path.home() / ".cache")
    return Path(base) / "hamrkq"


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


def _versions() -> str:
    # Read from the module each time (a dictionary lookup), not bound at import.
    from hamrkq import _version

    return f"codegen={CODEGEN_VERSION};hamrkq={_version.__version__};{_tool_versions()}"


def cache_key(ham: Hamiltonian, extra: str = "") -> str:
    """Hex digest naming the generated module of ``ham``.

    The key hashes ``srepr`` of H and of the ordered coordinates, momenta,
    parameters and time symbol (everything generated is derived from these, in
    this order), the versions of this generator, hamrkq, SymPy (which does the
    derivation), numba and Python, and ``extra`` (for instance a method name).
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


class _ScalarPrinter(PythonCodePrinter):
    """PythonCodePrinter with symbols renamed and floats printed exactly."""

    def __init__(self, names: dict[sp.Symbol, str]):
        super().__init__({"fully_qualified_modules": True, "standard": "python3"})
        self._names = names

    def _print_Symbol(self, expr: sp.Symbol) -> str:
        # check_supported has already proved every symbol is in the table.
        return self._names[expr]

    def _print_Pow(self, expr: sp.Pow, rational: bool = False) -> str:
        # Integer powers are spelled out so that every backend computes the
        # same bits: Python's float ** int calls the C library's pow(), while
        # numba multiplies (by squaring).  Products for |n| <= 4, otherwise a
        # float exponent, which both send to pow().
        exponent = expr.exp
        if exponent.is_Integer and abs(int(exponent)) >= 2:
            n = int(exponent)
            base = self.parenthesize(expr.base, PRECEDENCE["Mul"], strict=True)
            if abs(n) <= MAX_PRODUCT_POWER:
                # Parenthesised: the product stands where a Pow (which binds
                # tighter than * and /) stood, as in a/b**2 -> a/(b*b).
                product = "*".join([base] * abs(n))
                return f"({product})" if n > 0 else f"(1/({product}))"
            base = self.parenthesize(expr.base, PRECEDENCE["Pow"], strict=True)
            return f"{base}**{float(n)!r}" if n > 0 else f"{base}**({float(n)!r})"
        return super()._print_Pow(expr, rational=rational)

    def _print_Float(self, expr: sp.Float) -> str:
        # repr(float) round-trips; SymPy's default prints 15 digits and loses bits.
        return repr(float(expr))


def _is_half_integer_power(expr: sp.Expr) -> bool:
    return expr.is_Pow and expr.exp.is_Rational and expr.exp.q == 2


def _hoist_power_bases(replacements, reduced, temps):
    """Give every compound base of an integer power its own temporary, and
    every base of a half-integer power its square root.

    The printer spells ``b**3`` as ``b*b*b``; without this, a base such as
    ``cos(q)`` would be computed three times.  A half-integer power
    ``b**(k + 1/2)`` becomes ``b**k * s`` with ``s = sqrt(b)`` a temporary
    shared by every power of ``b`` (``1/(b*s)`` for ``b**(-3/2)``): one
    square root and a few products per particle pair of an N-body force and
    its Jacobian, instead of a ``pow`` call for each of ``r**-3`` and
    ``r**-5``.  ``sqrt``, ``*`` and ``/`` are correctly rounded, so both
    backends compute the same bits.  Bases are hoisted just before the
    temporary (or output) that uses them, so definitions still precede uses.
    """
    known: dict[sp.Expr, sp.Symbol] = {}
    roots: dict[sp.Expr, sp.Symbol] = {}
    ordered: list[tuple[sp.Symbol, sp.Expr]] = []

    def hoist(base: sp.Expr) -> sp.Expr:
        if base.is_Atom:
            return base
        symbol = known.get(base)
        if symbol is None:
            symbol = known[base] = next(temps)
            ordered.append((symbol, base))
        return symbol

    def visit(expr: sp.Expr) -> sp.Expr:
        if expr.is_Atom:
            return expr
        args = tuple(visit(arg) for arg in expr.args)
        if args != expr.args:
            expr = expr.func(*args, evaluate=False)
        if _is_half_integer_power(expr) and expr.exp != sp.S.Half:
            base = hoist(expr.base)
            root = roots.get(base)
            if root is None:
                root = roots[base] = next(temps)
                ordered.append((root, sp.sqrt(base, evaluate=False)))
            k = abs(expr.exp.p) // 2  # |exponent| = k + 1/2
            if k == 0:
                magnitude = root
            elif k == 1:
                magnitude = sp.Mul(base, root, evaluate=False)
            else:
                magnitude = sp.Mul(sp.Pow(base, k, evaluate=False), root, evaluate=False)
            return magnitude if expr.exp > 0 else sp.Pow(magnitude, -1, evaluate=False)
        if expr.is_Pow and expr.exp.is_Integer and abs(int(expr.exp)) >= 2:
            return sp.Pow(hoist(expr.base), expr.exp, evaluate=False)
        return expr

    for symbol, value in replacements:
        ordered.append((symbol, visit(value)))
    outputs = [visit(value) for value in reduced]
    return ordered, outputs


def _body(
    exprs: Sequence[sp.Expr],
    targets: Sequence[str],
    names: dict[sp.Symbol, str],
    temp_prefix: str = "c",
) -> tuple[list[str], list[str]]:
    """CSE of ``exprs``: the lines assigning the temporaries (named
    ``<temp_prefix>0, 1, ...``) and those assigning each target."""
    temps = sp.numbered_symbols("_c")
    replacements, reduced = sp.cse(list(exprs), symbols=temps, order="none")
    replacements, reduced = _hoist_power_bases(replacements, reduced, temps)
    names = dict(names)
    for k, (symbol, _) in enumerate(replacements):
        names[symbol] = f"{temp_prefix}{k}"
    printer = _ScalarPrinter(names)
    temporaries = [
        f"    {names[symbol]} = {printer.doprint(value)}" for symbol, value in replacements
    ]
    outputs = [
        f"    {target} = {printer.doprint(value)}"
        for target, value in zip(targets, reduced, strict=True)
    ]
    return temporaries, outputs


def _block(
    name: str,
    signature: str,
    doc: str,
    exprs: Sequence[sp.Expr],
    targets: Sequence[str],
    names: dict[sp.Symbol, str],
    prologue: Sequence[str] = (),
    returns: bool = False,
) -> list[str]:
    """Lines of one function: CSE temporaries, then one assignment per target.

    The targets (array items) are assigned last, from local values: with no
    store between the loads, the compiler may share the loads of ``y`` and
    the calls on them (a sine and a cosine of the same angle become one
    ``sincos``), which it cannot when a store to ``out`` might change ``y``.
    The ``prologue`` (zeroing the output) runs after the computation too.
    """
    if returns:
        temporaries, outputs = _body(exprs, ["return"], names)
        outputs = [line.replace("return = ", "return ", 1) for line in outputs]
        stores: list[str] = []
    else:
        values = [f"r{k}" for k in range(len(targets))]
        temporaries, outputs = _body(exprs, values, names)
        stores = [*prologue, *(f"    {t} = {v}" for t, v in zip(targets, values, strict=True))]
    return [f"def {name}({signature}):", f'    """{doc}"""', *temporaries, *outputs, *stores]


def _rhs_jvp_block(rhs, jac, nonzero, dim: int, names: dict[sp.Symbol, str]) -> list[str]:
    """``rhs_jvp(t, y, params, v, out, dout, JM)``: f into ``out`` and J v
    into ``dout`` (``JM`` is a scratch Jacobian).

    Above :data:`MAX_FUSED_DIM` it calls ``rhs``, ``jac`` (into ``JM``) and
    adds the rows of ``JM v`` in order, which is quick to compile.  Up to it:

    The bodies of ``rhs`` and ``jac`` are repeated verbatim (their own CSE, so
    f and every entry of J are the same expressions, evaluated in the same
    order, as in those functions), and each row of J v is added in the order
    k = 0, 1, ..., from 0.0, zero entries included: exactly what ``rhs``, then
    ``jac`` and the loop's matrix-vector product compute, bit for bit.  One
    call instead of two, and the compiler evaluates the sines and cosines
    that f and J share once (they are the same pure expressions).
    """
    if dim > MAX_FUSED_DIM:
        return [
            "def rhs_jvp(t, y, params, v, out, dout, JM):",
            '    """out[:] = dy/dt and dout[:] = Jacobian of rhs at y, times v."""',
            "    rhs(t, y, params, out)",
            "    jac(t, y, params, JM)",
            "    for i in range(JM.shape[0]):",
            "        acc = 0.0",
            "        for k in range(JM.shape[1]):",
            "            acc += JM[i, k] * v[k]",
            "        dout[i] = acc",
        ]
    # Everything is read before anything is written: with no stores in
    # between, the compiler may share the loads and the calls of f and J
    # (it cannot assume that out, dout, y and v do not overlap).
    f_temps, f_out = _body(rhs, [f"r{i}" for i in range(dim)], names, "f")
    entry = {(i, j): f"j{i}_{j}" for i, j in nonzero}
    j_temps, j_out = _body([jac[i, j] for i, j in nonzero], list(entry.values()), names, "g")
    rows = []
    for i in range(dim):
        terms = [f"{entry.get((i, k), '0.0')}*v[{k}]" for k in range(dim)]
        rows.append(f"    d{i} = " + "(" * dim + "0.0 + " + ") + ".join(terms) + ")")
    stores = [f"    out[{i}] = r{i}" for i in range(dim)]
    stores += [f"    dout[{i}] = d{i}" for i in range(dim)]
    return [
        "def rhs_jvp(t, y, params, v, out, dout, JM):",
        '    """out[:] = dy/dt and dout[:] = Jacobian of rhs at y, times v."""',
        *f_temps, *f_out, *j_temps, *j_out, *rows, *stores,
    ]  # fmt: skip


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

    lines = [
        '"""Generated by hamrkq.backends.codegen: do not edit (the file is rewritten when',
        "its hash changes).  State y = (q..., p...); params ordered like",
        f'Hamiltonian.parameters.  dim = {dim}, parameters = {len(ham.parameters)}."""',
        "",
        "import math",
        "",
        f"DIM = {dim}",
        f"NPARAMS = {len(ham.parameters)}",
        f"CODEGEN_VERSION = {CODEGEN_VERSION}",
        "",
        "",
    ]
    lines += _block(
        "rhs",
        "t, y, params, out",
        "out[:] = dy/dt = (dH/dp, -dH/dq).",
        rhs,
        [f"out[{i}]" for i in range(dim)],
        names,
    )
    lines += ["", ""]
    lines += _block(
        "jac",
        "t, y, params, out",
        "out[:, :] = Jacobian of rhs with respect to y.",
        [jac[i, j] for i, j in nonzero],
        [f"out[{i}, {j}]" for i, j in nonzero],
        names,
        # Zeros first: callers reuse the output array between calls.
        prologue=["    out[:, :] = 0.0"],
    )
    lines += ["", ""]
    lines += _block(
        "jvp",
        "t, y, params, v, out",
        "out[:] = Jacobian of rhs at y, times v.",
        products,
        [f"out[{i}]" for i in range(dim)],
        names,
    )
    lines += ["", ""]
    lines += _rhs_jvp_block(rhs, jac, nonzero, dim, names)
    lines += ["", ""]
    lines += _block("energy", "t, y, params", "H at one state.", [ham.H], [], names, returns=True)
    lines += [
        "",
        "",
        "def energy_rows(t, Y, params, out):",
        '    """out[i] = H(t[i], Y[i]) for every row of Y."""',
        "    for i in range(Y.shape[0]):",
        "        out[i] = energy(t[i], Y[i], params)",
    ]
    return "\n".join(lines) + "\n"


def _write_atomically(path: Path, text: str) -> None:
    with atomic_file(path, "w") as handle:
        handle.write(text)


def _import_file(name: str, path: Path) -> ModuleType:
    spec = importlib.util.spec_from_file_location(name, path)
    if spec is None or spec.loader is None:  # pragma: no cover - a .py path always has one
        raise ImportError(f"cannot import generated module {path}")
    module = importlib.util.module_from_spec(spec)
    # Registered before executing, as importlib does, so numba can find the
    # module of the functions it compiles.
    sys.modules[name] = module
    try:
        spec.loader.exec_module(module)
    except BaseException:
        sys.modules.pop(name, None)
        raise
    return module


def _checksum_line(text: str) -> str:
    return CHECKSUM_PREFIX + hashlib.sha256(text.encode("utf-8")).hexdigest()


def _sealed(text: str) -> str:
    """``text`` followed by its checksum line."""
    if not text.endswith("\n"):
        text += "\n"
    return text + _checksum_line(text) + "\n"


def _damage(path: Path) -> str | None:
    """Why the cached file at ``path`` cannot be trusted, or None if it is intact.

    Intact means: readable as UTF-8, and its last line is the checksum of the
    text before it (so an emptied, truncated or edited file is caught before
    it is imported, or compiled by numba).
    """
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        return "it is not valid UTF-8"
    body, _, last = text.rstrip("\n").rpartition("\n")
    if not text.strip():
        return "it is empty"
    if not last.startswith(CHECKSUM_PREFIX):
        return "its checksum line is missing (truncated?)"
    if last != _checksum_line(body + "\n"):
        return "its checksum does not match its contents"
    return None


def load_source(key: str, make_source, directory: Path | None = None) -> ModuleType:
    """Import the module cached under ``key``, writing it first if needed.

    ``make_source()`` is called only when the file does not exist yet or is
    damaged.  Every file ends with a checksum of its text
    (:data:`CHECKSUM_PREFIX`), verified before the import: a damaged file
    (emptied, truncated, edited) is rebuilt from ``make_source()`` with one
    :class:`~hamrkq.errors.HamrkqWarning` that names it, instead of failing
    to import, or to compile, on every later run.  The rewritten file has a
    new modification time, so numba's index of machine code compiled from
    the old text no longer matches it and is recompiled too.

    The file is written atomically (a temporary name, then a rename), so
    processes that race to create it both end up importing a complete file.
    Imported modules are remembered for the rest of the process.
    """
    directory = cache_dir() if directory is None else directory
    path = module_path(key, directory)
    name = path.stem
    with _MODULE_LOCK:
        module = _LOADED.get(str(path))
        if module is not None:
            return module
        directory.mkdir(parents=True, exist_ok=True)
        if not path.exists():
            _write_atomically(path, _sealed(make_source()))
        else:
            damage = _damage(path)
            if damage is not None:
                warnings.warn(
                    f"hamrkq: the cached file {path} is damaged ({damage}); "
                    "rebuilding it (and the compiled code kept beside it)",
                    HamrkqWarning,
                    stacklevel=_caller_level(),
                )
                _write_atomically(path, _sealed(make_source()))
        module = _import_file(name, path)
        _LOADED[str(path)] = module
        return module


def _caller_level() -> int:
    """The ``stacklevel`` that points a warning at the first frame outside hamrkq
    (load_source is reached through solve, compiled, numeric... at varying depths)."""
    frame = sys._getframe(1)
    level = 1
    package = str(Path(__file__).resolve().parents[1])
    while frame is not None and frame.f_code.co_filename.startswith(package):
        frame = frame.f_back
        level += 1
    return level


def module_path(key: str, directory: Path | None = None) -> Path:
    """Where the module cached under ``key`` lives (whether or not it exists)."""
    directory = cache_dir() if directory is None else directory
    return directory / f"{MODULE_PREFIX}{key[:32]}.py"


def is_cached(ham: Hamiltonian, directory: Path | None = None) -> bool:
    """True if the generated module of ``ham`` is on disk and intact (its
    checksum matches), so :func:`load_module` will neither derive nor print
    anything.  A caller can use it to announce a slow first use (generation,
    then compilation) before it starts."""
    path = module_path(cache_key(ham), directory)
    try:
        return path.exists() and _damage(path) is None
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
