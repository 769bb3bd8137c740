"""The output directory of a command: claimed under a lock, written atomically.

:class:`OutputDir` applies the output-directory policy (an existing non-empty
directory is refused unless ``force``; a directory another hamrkq command is
writing into is always refused) and writes every file atomically (a
temporary name in the same directory, then :func:`os.replace`), so a crash
or Ctrl-C never leaves a half-written file under its final name.
:func:`check_dpi` bounds ``--dpi``, and :data:`MAX_FIGURE_PIXELS` the size of
a figure written.
"""

from __future__ import annotations

import errno
import json
import os
import tempfile
import weakref
from pathlib import Path
from typing import Any

from hamrkq._files import jsonable, write_atomic
from hamrkq.errors import InputError

try:  # POSIX: an advisory lock that dies with its process (a stale lock frees itself)
    import fcntl
except ImportError:  # pragma: no cover - Windows: exclusive creation only
    fcntl = None  # type: ignore[assignment]


__all__ = [
    "LOCK_NAME",
    "MAX_DPI",
    "MAX_FIGURE_PIXELS",
    "MIN_DPI",
    "OWN_FILES",
    "OutputDir",
    "check_dpi",
    "close_all",
    "is_own",
]


#: Files that hamrkq's commands write, by their exact names: with ``force``
#: these (and only these) are removed first, so that no stale figure from an
#: earlier run sits beside the new results.  A user's own files are never
#: touched.  Every name a command writes must be one (tests/test_cli_force.py
#: runs each command and checks its files): ``solution.csv``, the ensemble's
#: and the section's files were missing, and ``--force`` left them stale
#: beside the new results.  Exact names, not patterns: ``solution*.npz`` and
#: ``figure[0-9]_*.png`` also deleted a user's ``solution_previous.npz`` (a
#: copy of an earlier result) and ``figure9_x.png`` (found by QA).
OWN_FILES = (
    "summary.json",
    # run, reproduce (solution_<method>.npz for the paper's two methods), compare
    "solution.npz",
    "solution_rk34q8.npz",
    "solution_rk34.npz",
    "solution.csv",
    "figure1_solution.png",
    "figure2_global_error.png",
    "figure2_global_error_true.png",
    "figure3_trajectory_error.png",
    "figure3_trajectory_error_true.png",
    "figure4_rk8_error.png",
    "comparison.md",
    "comparison.csv",
    "comparison.json",
    "work_precision.png",
    "energy_error.png",
    # ensemble
    "ensemble.npz",
    "ensemble_map.png",
    "ensemble_orbits.png",
    # poincare
    "section.npz",
    "section.png",
)


#: Name of the lock file a command holds in its output directory while it
#: writes there; removed when the command ends.
LOCK_NAME = ".hamrkq.lock"

#: Bounds on ``--dpi``.  The largest figure (10 x 7 inches) at 600 dpi is
#: 25 megapixels, about 100 MB in memory while it is drawn; 5000 dpi would need
#: 7 GB and minutes.
MIN_DPI = 10
MAX_DPI = 600
#: Largest figure written, in pixels (width x height at the chosen dpi).
MAX_FIGURE_PIXELS = 30_000_000


def is_own(name: str) -> bool:
    """Whether a file name is one of hamrkq's outputs (:data:`OWN_FILES`),
    which ``--force`` removes."""
    return name in OWN_FILES


def check_dpi(dpi: int) -> int:
    """``dpi`` if it is within [:data:`MIN_DPI`, :data:`MAX_DPI`], else an InputError."""
    if not MIN_DPI <= dpi <= MAX_DPI:
        raise InputError(
            f"--dpi must be between {MIN_DPI} and {MAX_DPI}, got {dpi} "
            f"(at {MAX_DPI} dpi the largest figure is already 25 megapixels)"
        )
    return dpi


# -- files -------------------------------------------------------------------
#: Output directories claimed and not yet closed (see :func:`close_all`).
_OPEN: weakref.WeakSet[OutputDir] = weakref.WeakSet()


def close_all() -> None:
    """Close every :class:`OutputDir` still open: the command line calls this
    when a command ends, however it ends."""
    for out in list(_OPEN):
        out.close()


def _take_lock(lock: Path) -> int | None:
    """An open descriptor holding ``lock``, or None when another process holds it."""
    if fcntl is None:  # pragma: no cover - Windows
        try:
            return os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
        except FileExistsError:
            return None
    while True:
        fd = os.open(lock, os.O_CREAT | os.O_RDWR, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            os.close(fd)
            if exc.errno in (errno.EAGAIN, errno.EACCES, errno.EWOULDBLOCK):
                return None
            raise
        # The holder may have removed the file between our open and our lock:
        # then we locked an orphan; start again with the file now at that name.
        try:
            same = os.path.samestat(os.fstat(fd), os.stat(lock))
        except FileNotFoundError:
            same = False
        if same:
            os.ftruncate(fd, 0)
            os.write(fd, f"{os.getpid()}\n".encode())
            return fd
        os.close(fd)


def _release(fd: int, lock: Path, directory: Path, created: bool) -> None:
    """Remove the lock file, then let go of the lock; remove an unused new directory."""
    try:
        lock.unlink(missing_ok=True)
    except OSError:
        # The directory became unwritable during the command (whose results
        # could not be written either: exit 3): the lock is let go of with its
        # descriptor, and the next command takes the file left over.  It
        # ended the command in a traceback with exit 1 (found by QA).
        pass
    finally:
        os.close(fd)
    if created:
        _remove_empty(directory)


def _remove_empty(directory: Path) -> None:
    try:
        directory.rmdir()
    except OSError:  # not empty (results, or a user's files): keep it
        pass


def _umask() -> int:
    mask = os.umask(0o022)  # reading the umask means setting it; restore at once
    os.umask(mask)
    return mask


class OutputDir:
    """An output directory and the files written into it.

    Parameters
    ----------
    path : str or Path
        The directory; created (with its parents) when missing.
    force : bool
        Allow an existing non-empty directory.  hamrkq's own earlier outputs
        there (:data:`OWN_FILES`) are removed first; other files are kept.

    Raises
    ------
    InputError
        ``path`` is a file, or a non-empty directory and ``force`` is false,
        or another hamrkq command is writing into it (even with ``force``).

    Notes
    -----
    The directory is *claimed* when the object is made: a lock file
    (:data:`LOCK_NAME`, held with ``flock`` on POSIX) is created in it, and the
    "not empty" check is repeated under the lock.  Two commands started at the
    same time with the same ``--out`` therefore cannot both pass the check and
    mix their files: one of them is refused before it runs.  :meth:`close`
    (also the end of a ``with`` block, or the object's garbage collection)
    removes the lock, and the directory itself if this object created it and
    wrote nothing into it.  A lock left by a killed process is not held, and
    is taken over.
    """

    def __init__(self, path: str | os.PathLike, *, force: bool = False):
        self.path = Path(path)
        self.force = force
        self.written: list[str] = []
        self._ready = False
        # Check first (a bad --out fails before a long run, and without
        # creating anything), then claim the directory and check again.
        if self.path.exists() and not self.path.is_dir():
            raise InputError(f"--out {str(self.path)!r} exists and is not a directory")
        self._check_empty()
        self._check_writable()
        self._claim()

    def _check_empty(self) -> None:
        if self.force or not self.path.is_dir():
            return
        if any(entry.name != LOCK_NAME for entry in self.path.iterdir()):
            raise InputError(
                f"output directory {str(self.path)!r} exists and is not empty; "
                "pass --force to write into it, or choose another --out"
            )

    def _claim(self) -> None:
        """Create the directory if needed and take its lock (see Notes)."""
        created = False
        try:
            self.path.mkdir(parents=True)
            created = True
        except FileExistsError:
            if not self.path.is_dir():
                raise InputError(
                    f"--out {str(self.path)!r} exists and is not a directory"
                ) from None
        except OSError as exc:
            raise InputError(
                f"--out {str(self.path)!r} cannot be created ({exc.strerror or exc})"
            ) from None
        lock = self.path / LOCK_NAME
        try:
            fd = _take_lock(lock)
        except BaseException:
            if created:
                _remove_empty(self.path)
            raise
        if fd is None:
            if created:
                _remove_empty(self.path)
            raise InputError(
                f"output directory {str(self.path)!r} is being written by another hamrkq "
                f"command (it holds {LOCK_NAME}); wait for it or choose another --out"
            )
        self._finalizer = weakref.finalize(self, _release, fd, lock, self.path, created)
        _OPEN.add(self)
        try:
            self._check_empty()  # again, now that no other command can start writing
        except BaseException:
            self.close()
            raise

    def close(self) -> None:
        """Release the directory: remove the lock (and the directory, if this
        object created it and nothing was written)."""
        finalizer = getattr(self, "_finalizer", None)
        if finalizer is not None:
            finalizer()

    def __enter__(self) -> OutputDir:
        return self

    def __exit__(self, *exc_info: Any) -> None:
        self.close()

    def _check_writable(self) -> None:
        """Refuse an --out that cannot be written, before any long run.

        Probes the nearest existing ancestor by creating and removing a
        temporary directory (permission bits alone say nothing to root, nor
        about read-only or virtual file systems); nothing is left behind.
        """
        ancestor = self.path.absolute()
        while not ancestor.exists():
            ancestor = ancestor.parent
        try:
            os.rmdir(tempfile.mkdtemp(prefix=".hamrkq-probe-", dir=ancestor))
        except OSError as exc:
            raise InputError(
                f"--out {str(self.path)!r} cannot be written ({exc.strerror or exc})"
            ) from None

    def _prepare(self) -> None:
        if self._ready:
            return
        if self.force and self.path.is_dir():  # under our lock: only our own old files
            for old in self.path.iterdir():
                if is_own(old.name) and old.is_file():
                    old.unlink()
        self.path.mkdir(parents=True, exist_ok=True)
        self._ready = True

    def _record(self, path: Path) -> Path:
        # mkstemp creates files readable by their owner only; results are
        # ordinary files, so give them the permissions the umask allows.
        os.chmod(path, 0o666 & ~_umask())
        self.written.append(path.name)
        return path

    def file(self, name: str) -> Path:
        """The path of ``name`` inside the directory (created on first use)."""
        self._prepare()
        return self.path / name

    def text(self, name: str, text: str) -> Path:
        """Write a text file atomically."""
        return self._record(write_atomic(self.file(name), text))

    def json(self, name: str, data: Any) -> Path:
        """Write strict JSON atomically (see :func:`jsonable`)."""
        text = json.dumps(jsonable(data), indent=2, allow_nan=False) + "\n"
        return self._record(write_atomic(self.file(name), text))

    def solution(self, name: str, solution: Any) -> Path:
        """:meth:`hamrkq.Solution.save` (atomic itself)."""
        return self._record(solution.save(self.file(name)))

    def figure(self, name: str, fig: Any, *, dpi: int = 120) -> Path:
        """:func:`hamrkq.plotting.figures.save_figure` (atomic itself).

        Raises
        ------
        InputError
            The image would exceed :data:`MAX_FIGURE_PIXELS` pixels.
        """
        from hamrkq.plotting.figures import save_figure

        width, height = fig.get_size_inches()
        pixels = width * dpi * height * dpi
        if not pixels <= MAX_FIGURE_PIXELS:
            raise InputError(
                f"{name}: {width:g} x {height:g} inches at {dpi} dpi is {pixels / 1e6:.0f} "
                f"megapixels; the limit is {MAX_FIGURE_PIXELS / 1e6:.0f}"
            )
        return self._record(save_figure(fig, self.file(name), dpi=dpi))
