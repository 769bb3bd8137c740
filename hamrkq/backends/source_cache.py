"""The disk cache of generated modules: where it is, how files are named, written, checked.

Every file is written atomically and ends with a checksum of its text
(:data:`CHECKSUM_PREFIX`), verified before it is imported: a damaged file is
rebuilt, not imported (:func:`load_source`).  Imported modules are remembered
for the rest of the process.  :mod:`hamrkq.backends.codegen` names the files
(its ``cache_key``) and supplies their text.
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
import sys
import threading
import warnings
from pathlib import Path
from types import ModuleType

from hamrkq._files import atomic_file
from hamrkq.errors import HamrkqWarning

__all__ = [
    "CACHE_ENV",
    "CHECKSUM_PREFIX",
    "MODULE_PREFIX",
    "cache_dir",
    "damage_of",
    "load_source",
    "module_path",
    "sealed",
]


#: Environment variable that overrides the cache directory.
CACHE_ENV = "HAMRKQ_CACHE_DIR"
#: Prefix of generated module names (``sys.modules`` keys and file stems).
MODULE_PREFIX = "hamrkq_gen_"

_MODULE_LOCK = threading.Lock()
_LOADED: dict[str, ModuleType] = {}
#: The last line of every cached file: ``CHECKSUM_PREFIX`` + the SHA-256 of
#: the file's name (its stem, which holds its key) and the text before it.
#: A file whose last line does not match (truncated, emptied, edited, or a
#: file of another key copied under this one's name) is rebuilt, not
#: imported.
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


def _checksum_line(name: str, text: str) -> str:
    """The checksum line of ``text`` in the file named ``name`` (its stem):
    the name is hashed with the text, so that a file of another system copied
    under this one's name is not taken for it (with the text's checksum
    alone it was, and the wrong equations were integrated: found by QA)."""
    return CHECKSUM_PREFIX + hashlib.sha256(f"{name}\n{text}".encode()).hexdigest()


def sealed(text: str, name: str) -> str:
    """``text`` followed by its checksum line, for the file named ``name``."""
    if not text.endswith("\n"):
        text += "\n"
    return text + _checksum_line(name, text) + "\n"


def damage_of(path: Path) -> str | None:
    """Why the cached file at ``path`` cannot be trusted, or None if it is intact.

    Intact means: readable as UTF-8, and its last line is the checksum of
    its name and the text before it (so an emptied, truncated or edited file,
    or another key's file under this name, is caught before it is imported,
    or compiled by numba).
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
    if last != _checksum_line(path.stem, body + "\n"):
        return "its checksum does not match its contents and name"
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
            _write_atomically(path, sealed(make_source(), name))
        else:
            damage = damage_of(path)
            if damage is not None:
                try:
                    _write_atomically(path, sealed(make_source(), name))
                except OSError as exc:
                    # A read-only cache: said once, as the reason the compiled
                    # backend cannot be used, and not "rebuilding it" (twice,
                    # with nothing rebuilt: found by QA).
                    raise OSError(
                        f"the cached file {path} is damaged ({damage}) and cannot be "
                        f"rebuilt there ({exc.strerror or exc})"
                    ) from exc
                warnings.warn(
                    f"hamrkq: the cached file {path} is damaged ({damage}): "
                    "rebuilt it (and the compiled code kept beside it)",
                    HamrkqWarning,
                    stacklevel=_caller_level(),
                )
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
