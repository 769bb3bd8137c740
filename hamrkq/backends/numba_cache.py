"""numba's disk cache with checksums: a damaged entry is rebuilt, never loaded.

Why: numba keeps a compiled function's machine code in two kinds of file, an
index (``<function>-<line>.pyXY.nbi``: which data file holds which
signature) and one data file per signature (``...pyXY.<n>.nbc``: the pickled
compile result with its object code), and checks neither.  Measured on numba
0.68 (a small function, then the step kernel): a truncated file or an
emptied one raised ``UnpicklingError: pickle data was truncated`` or
``EOFError`` out of the compile on every later run, bytes overwritten in
the middle ``RuntimeError: LLVM bitcode parsing error`` (a data file) or
``UnicodeDecodeError`` (an index), and one flipped bit inside the object
code was loaded and run without a word.  hamrkq then fell back to the
interpreted loop (about 100 times slower) on every run, for good, and
``hamrkq compile`` ended in a traceback.

What :func:`compile_checked` changes, for the functions hamrkq compiles
(:func:`hamrkq.backends.numba_compile.jit`):

- every index and data file numba writes ends with the SHA-256 of what
  precedes it (:data:`CHECKSUM_MARK` and 64 hex digits), after numba's own
  pickles: unpickling ignores trailing bytes, so numba alone still reads
  the files;
- a file is checked before anything in it is unpickled.  One whose
  checksum is missing or does not match, that cannot be read or unpickled,
  or whose compile result numba cannot rebuild is a damaged entry
  (:class:`DamagedEntry`): it is removed (a data file: that signature only;
  an index: the index and that function's data files, which nothing names
  any more), and numba compiles the function again and saves it as it
  always does, to a temporary name renamed into place.  ``jit`` then warns
  once, naming the file, or, if compiling again fails too, raises with the
  file and the real reason;
- an index that names a data file which does not exist is numba's ordinary
  miss, compiled again without a warning: another process may be between
  writing the index and the data file.

Two processes may find the same damaged file.  Each removes it only if it
is still the file it read (same device, inode, size and modification time),
so a process never deletes the entry another has just rebuilt; both
compile, and numba's rename makes the last complete file win.  A process
that loses that race at worst removes a good file, which the next process
finds missing and compiles again: nothing damaged is ever loaded.

numba's internals are not an API: the change applies only where every
method it overrides is where it was (:func:`applicable`); otherwise numba
caches as it always does.  numba is imported only when something is
compiled.
"""

from __future__ import annotations

import functools
import hashlib
import io
import os
import pickle
import re
from collections.abc import Callable
from typing import Any

__all__ = [
    "CACHE_FORMAT",
    "CHECKSUM_MARK",
    "DamagedEntry",
    "applicable",
    "compile_checked",
    "error_text",
    "sealed",
]

#: Version of the files' layout (numba's pickles, then the checksum); part of
#: every cache key (:func:`hamrkq.backends.codegen._versions`), so files
#: written without a checksum by an earlier hamrkq are never met, and never
#: reported as damaged.
CACHE_FORMAT = 1

#: What precedes the checksum (64 hex digits of SHA-256) at the end of every
#: index and data file.
CHECKSUM_MARK = b"\n# hamrkq-checksum: sha256="
_DIGEST_SIZE = 64

#: What identifies the file that was read: device, inode, size and
#: modification time (a file renamed into place by another process differs).
Identity = tuple[int, int, int, int]


class DamagedEntry(Exception):
    """A file of numba's cache that cannot be trusted.

    Not an ``OSError``: numba takes an ``OSError`` while it reads a data file
    for a missing file (a miss) and would swallow it.

    Parameters
    ----------
    path : str
        The damaged file.
    reason : str
        Why it cannot be trusted ("it is empty", "its checksum does not
        match its contents", ...).
    identity : tuple of int, optional
        :data:`Identity` of the file that was read, when it was read.
    """

    def __init__(self, path: str, reason: str, identity: Identity | None = None):
        super().__init__(f"{path}: {reason}")
        self.path = path
        self.reason = reason
        self.identity = identity
        #: Why the file could not be removed, or None if it was (or is gone).
        self.not_removed: str | None = None


def sealed(body: bytes) -> bytes:
    """``body`` followed by :data:`CHECKSUM_MARK` and its SHA-256."""
    return body + CHECKSUM_MARK + hashlib.sha256(body).hexdigest().encode("ascii")


def _verified(raw: bytes, path: str, identity: Identity) -> bytes:
    """The body of a sealed file (:func:`sealed`); raises :class:`DamagedEntry`
    if it is empty, has no checksum or a wrong one."""
    if not raw:
        raise DamagedEntry(path, "it is empty", identity)
    cut = len(raw) - _DIGEST_SIZE - len(CHECKSUM_MARK)
    if cut < 0 or raw[cut : cut + len(CHECKSUM_MARK)] != CHECKSUM_MARK:
        reason = "it has no checksum at its end: truncated, or not written by hamrkq"
        raise DamagedEntry(path, reason, identity)
    body, digest = raw[:cut], raw[cut + len(CHECKSUM_MARK) :]
    if hashlib.sha256(body).hexdigest().encode("ascii") != digest:
        raise DamagedEntry(path, "its checksum does not match its contents", identity)
    return body


def _read(path: str) -> tuple[bytes, Identity]:
    """The bytes of ``path`` and the :data:`Identity` of the file read."""
    with open(path, "rb") as handle:
        raw = handle.read()
        stat = os.fstat(handle.fileno())
    return raw, (stat.st_dev, stat.st_ino, stat.st_size, stat.st_mtime_ns)


def error_text(exc: BaseException) -> str:
    """``Type: first line of the message`` of ``exc``; an ``OSError``'s without
    the paths (a message about a cache file names it already)."""
    text = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
    first = text.splitlines()[0] if text else ""
    return f"{type(exc).__name__}: {first}"


def _unreadable(path: str, exc: BaseException, identity: Identity | None = None) -> DamagedEntry:
    return DamagedEntry(path, f"it cannot be read ({error_text(exc)})", identity)


def _remove(damage: DamagedEntry) -> bool:
    """Remove the damaged file if it is still the one that was read; whether
    this process removed it (``damage.not_removed`` says why not, if it
    could not)."""
    try:
        if damage.identity is not None:
            stat = os.stat(damage.path)
            now = (stat.st_dev, stat.st_ino, stat.st_size, stat.st_mtime_ns)
            if now != damage.identity:
                return False  # another process has written it again meanwhile
        os.unlink(damage.path)
    except FileNotFoundError:
        return False  # another process removed it
    except OSError as exc:
        damage.not_removed = error_text(exc)
        return False
    return True


@functools.cache
def applicable() -> bool:
    """Whether numba's cache is laid out as :func:`compile_checked` expects:
    every method it overrides or calls present (asked once per process)."""
    try:
        from numba.core import caching, typeinfer
        from numba.core.dispatcher import Dispatcher
    except Exception:  # numba missing, or laid out otherwise
        return False
    needed: dict[Any, tuple[str, ...]] = {
        caching.IndexDataCacheFile: (
            "_load_index", "_save_index", "_load_data", "_save_data",
            "_dump", "_open_for_write", "_data_path", "load", "save",
        ),
        caching.FunctionCache: ("load_overload", "save_overload", "_impl_class"),
        caching.CompileResultCacheImpl: ("_locator_classes",),
        caching.UserProvidedCacheLocator: ("ensure_cache_path", "get_cache_path"),
        Dispatcher: ("compile", "disable_compile", "enable_caching"),
        typeinfer: ("register_dispatcher",),
    }  # fmt: skip
    return all(hasattr(owner, name) for owner, names in needed.items() for name in names)


def _load_index(cache_file: Any) -> dict:
    """numba's ``_load_index`` with the checksum verified first: the index's
    ``{key: data file name}``, or ``{}`` when it is missing, another numba's
    or stale (numba's own answers); raises :class:`DamagedEntry`."""
    path = cache_file._index_path
    try:
        raw, identity = _read(path)
    except FileNotFoundError:
        return {}
    except OSError as exc:
        raise _unreadable(path, exc) from exc
    body = _verified(raw, path, identity)
    try:
        stream = io.BytesIO(body)
        version = pickle.load(stream)
        if version != cache_file._version:
            return {}
        stamp, overloads = pickle.loads(stream.read())
        if not isinstance(overloads, dict):
            raise TypeError(f"the index holds a {type(overloads).__name__}")
    except Exception as exc:
        raise _unreadable(path, exc, identity) from exc
    # A stale index (the source file changed since) is numba's miss, as before.
    return overloads if stamp == cache_file._source_stamp else {}


def _load_data(cache_file: Any, name: str) -> Any:
    """numba's ``_load_data`` with the checksum verified first; a missing file
    raises FileNotFoundError (numba's miss: the index may be ahead of it),
    any other fault :class:`DamagedEntry`."""
    path = cache_file._data_path(name)
    try:
        raw, identity = _read(path)
    except FileNotFoundError:
        raise
    except OSError as exc:
        raise _unreadable(path, exc) from exc
    body = _verified(raw, path, identity)
    cache_file.loaded = (path, identity)
    try:
        return pickle.loads(body)
    except Exception as exc:
        raise _unreadable(path, exc, identity) from exc


def _remove_entry(cache_file: Any, damage: DamagedEntry) -> None:
    """Remove a damaged file; with a damaged index, the function's data files
    too: nothing names them any more, and numba numbers new ones from 1, so a
    stale one could be read under a new name before it is overwritten."""
    if not _remove(damage) or damage.path != cache_file._index_path:
        return
    data = re.compile(re.escape(cache_file.filename_base) + r"\.\d+\.nbc")
    try:
        names = os.listdir(cache_file._cache_path)
    except OSError:
        return
    for name in names:
        if data.fullmatch(name):
            try:
                os.unlink(os.path.join(cache_file._cache_path, name))
            except OSError:
                pass  # gone already: at worst a miss later


def _load_overload(cache: Any, load: Callable[[], Any]) -> Any:
    """``load()`` (numba's ``load_overload``); a damaged entry is removed,
    recorded in ``cache.damaged`` and taken for a miss (None), so that numba
    compiles the function and saves it again."""
    cache._cache_file.loaded = None
    try:
        return load()
    except DamagedEntry as exc:
        damage = exc
    except Exception as exc:
        # Read and checked, but numba cannot rebuild it.
        if cache._cache_file.loaded is None:
            raise  # not a cache file's fault
        path, identity = cache._cache_file.loaded
        damage = DamagedEntry(path, f"it cannot be loaded ({error_text(exc)})", identity)
    _remove_entry(cache._cache_file, damage)
    cache.damaged.append(damage)
    return None


@functools.cache
def _checked_cache_type(in_folder: bool = False) -> type:
    """numba's ``FunctionCache`` with the checks (defined on first use, so
    that importing this module does not import numba); ``in_folder``: only
    in numba's cache directory, the folder hamrkq gave (writable, or
    read-only), never numba's other places (beside the function's source:
    the kernel's machine code was written into hamrkq's own package where
    its folder could not be used, found by QA)."""
    from numba.core import caching

    class CheckedCacheFile(caching.IndexDataCacheFile):
        """numba's index and data files, each ending with its checksum."""

        def __init__(self, cache_path, filename_base, source_stamp):
            super().__init__(cache_path, filename_base, source_stamp)
            self.filename_base = filename_base
            #: (path, identity) of the data file last read, for a rebuild
            #: that fails after the file was read.
            self.loaded: tuple[str, Identity] | None = None

        def _save_index(self, overloads):
            # numba's layout (its version, then the stamp and the overloads),
            # sealed whole.
            body = pickle.dumps(self._version, protocol=-1)
            body += self._dump((self._source_stamp, overloads))
            with self._open_for_write(self._index_path) as handle:
                handle.write(sealed(body))

        def _load_index(self):
            return _load_index(self)

        def _save_data(self, name, data):
            with self._open_for_write(self._data_path(name)) as handle:
                handle.write(sealed(self._dump(data)))

        def _load_data(self, name):
            return _load_data(self, name)

    class ReadOnlyCacheLocator(caching.UserProvidedCacheLocator):
        """numba's cache directory (``NUMBA_CACHE_DIR``, or the folder hamrkq
        gives) where it can be read but not written: a cache filled by
        ``hamrkq compile`` and shipped read-only (a container image, a shared
        installation).  numba's own locator wants to write a file there
        first, so it passed over such a folder, compiled everything again
        into ``~/.cache/numba`` or, without a writable home, found no cache
        at all and hamrkq fell back to the interpreted loop (found by QA).
        Loaded from, never written (:meth:`CheckedFunctionCache.save_overload`)."""

        def ensure_cache_path(self):
            path = self.get_cache_path()
            readable = os.path.isdir(path) and os.access(path, os.R_OK | os.X_OK)
            if not readable or os.access(path, os.W_OK):
                raise OSError(f"{path} is not a read-only cache folder")

    class CheckedCacheImpl(caching.CompileResultCacheImpl):
        # numba's locators, with a read-only folder of its own cache
        # directory accepted right after a writable one.
        _locator_classes = (
            caching.UserProvidedCacheLocator,
            ReadOnlyCacheLocator,
            *(
                ()
                if in_folder
                else (
                    cls
                    for cls in caching.CompileResultCacheImpl._locator_classes
                    if cls is not caching.UserProvidedCacheLocator
                )
            ),
        )

    class CheckedFunctionCache(caching.FunctionCache):
        """numba's per-function cache whose damaged entries are removed and
        compiled again (:attr:`damaged` lists them); in a read-only folder,
        loaded from only (:attr:`not_saved` lists what was compiled and could
        not be kept)."""

        _impl_class = CheckedCacheImpl

        def __init__(self, py_func):
            super().__init__(py_func)
            self._cache_file = CheckedCacheFile(
                cache_path=self._cache_path,
                filename_base=self._impl.filename_base,
                source_stamp=self._impl.locator.get_source_stamp(),
            )
            self.damaged: list[DamagedEntry] = []
            self.not_saved: list[str] = []

        def save_overload(self, sig, data):
            if isinstance(self._impl.locator, ReadOnlyCacheLocator):
                self.not_saved.append(self._cache_path)
                return
            super().save_overload(sig, data)

        def load_overload(self, sig, target_context):
            parent = super().load_overload
            return _load_overload(self, lambda: parent(sig, target_context))

    return CheckedFunctionCache


def compile_checked(
    numba: Any,
    function: Callable,
    signature: Any,
    flags: dict[str, Any],
    damaged: list[DamagedEntry],
    in_folder: bool = False,
) -> Any:
    """``numba.njit(signature, cache=True, **flags)(function)``, with the
    cache checked (see the module's description); with ``in_folder``, cached
    only in numba's cache directory (the folder hamrkq gave), or, where that
    cannot be used, compiled without a cache (the dispatcher's ``_cache`` is
    then numba's null cache, ``uncached_reason`` says why).

    Parameters
    ----------
    numba : module
    function : callable
        The Python function to compile.
    signature : numba signature
    flags : dict
        numba's options, without ``cache``.
    damaged : list
        Receives a :class:`DamagedEntry` for every damaged file found (and
        removed); filled even when the compile then fails.

    Returns
    -------
    numba dispatcher
        Compiled for ``signature`` (or loaded from the cache), compiling no
        other signature.
    """
    if not applicable():
        return numba.njit(signature, cache=True, **flags)(function)
    from numba.core import typeinfer

    # As numba.njit(signature, cache=True) does, with the checked cache put in
    # before the first compile.
    dispatcher = numba.njit(**flags)(function)
    try:
        cache = _checked_cache_type(in_folder)(dispatcher.py_func)
    except RuntimeError as exc:  # numba: "cannot cache function ...: no locator available"
        if not in_folder:
            raise
        dispatcher.uncached_reason = error_text(exc)
        cache = None  # numba's null cache stays
    else:
        dispatcher._cache = cache
    try:
        with typeinfer.register_dispatcher(dispatcher):
            dispatcher.compile(signature)
    finally:
        if cache is not None:
            damaged.extend(cache.damaged)
    dispatcher.disable_compile()
    return dispatcher
