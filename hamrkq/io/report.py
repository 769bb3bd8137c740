"""Shared pieces of the ``run`` and ``reproduce`` commands: output files and reports.

- :class:`OutputDir`: the output-directory policy (an existing non-empty
  directory is refused unless ``force``; a directory another hamrkq command
  is writing into is always refused) and atomic writing of every file
  (a temporary name in the same directory, then :func:`os.replace`), so a
  crash or Ctrl-C never leaves a half-written file under its final name.
- :func:`check_dpi`: the bounds on ``--dpi``.
- :func:`summary_dict`: the content of ``summary.json`` for one run: the
  settings, every number :func:`hamrkq.analysis.diagnostics.diagnose` found, the
  counters, wall times, the status and the package versions.
- :func:`summary_rows` and :func:`format_table`: the text table printed on
  stdout.
- :class:`ProgressBar`: a progress bar on a terminal that appears only once a
  run has lasted about a second, and never when stderr is not a terminal.
"""

from __future__ import annotations

import datetime as _dt
import errno
import json
import math
import os
import platform
import sys
import tempfile
import time
import weakref
from collections.abc import Iterable, Mapping
from importlib import metadata
from pathlib import Path
from typing import Any, TextIO

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
    "SUMMARY_FORMAT_VERSION",
    "OutputDir",
    "ProgressBar",
    "check_dpi",
    "close_all",
    "format_table",
    "jsonable",
    "package_versions",
    "summary_dict",
    "summary_rows",
    "write_atomic",
]

#: Version of the layout of ``summary.json``; bumped when keys change meaning.
SUMMARY_FORMAT_VERSION = 1
#: Distributions whose versions go into ``summary.json`` (what a rerun needs).
VERSIONED = ("hamrkq", "numpy", "scipy", "sympy", "matplotlib", "numba")
#: Files that hamrkq's commands write, as glob patterns: with ``force`` these
#: (and only these) are removed first, so that no stale figure from an earlier
#: run sits beside the new results.  A user's own files are never touched.
OWN_FILES = (
    "summary.json",
    "comparison.md",
    "comparison.csv",
    "comparison.json",
    "solution*.npz",
    "figure[0-9]_*.png",
    "work_precision.png",
    "energy_error.png",
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
            for pattern in OWN_FILES:
                for old in self.path.glob(pattern):
                    if old.is_file():
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


# -- summary.json --------------------------------------------------------------
def package_versions() -> dict[str, str | None]:
    """Python, the platform and the versions of hamrkq and its dependencies."""
    from hamrkq._version import __version__

    versions: dict[str, str | None] = {
        "python": platform.python_version(),
        "platform": platform.platform(),
    }
    for name in VERSIONED:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            versions[name] = __version__ if name == "hamrkq" else None
    return versions


def summary_dict(
    solution: Any,
    diagnostics: Any,
    *,
    problem: Any = None,
    settings: Mapping[str, Any] | None = None,
    wall_time: Mapping[str, float] | None = None,
    notes: Iterable[str] = (),
) -> dict[str, Any]:
    """Everything about one run, for ``summary.json``.

    Parameters
    ----------
    solution : Solution
    diagnostics : Diagnostics or None
        From :func:`hamrkq.analysis.diagnostics.diagnose`; its :meth:`to_dict` is stored
        unchanged under ``"diagnostics"``, so the file and a library call with
        the same settings agree number for number.
    problem : Problem, optional
    settings : mapping, optional
        The command's own settings (reference kind, output options, ...);
        the solution's ``options`` (what :func:`hamrkq.solve` actually used)
        are stored beside them.
    wall_time : mapping, optional
        Seconds, by phase.
    notes : iterable of str
        Caveats the command found (besides the diagnostics' own notes).
    """
    out: dict[str, Any] = {
        "format_version": SUMMARY_FORMAT_VERSION,
        "created": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
    }
    if problem is not None:
        out["problem"] = {
            "name": problem.name,
            "title": problem.title,
            "file": None if problem.path is None else str(problem.path),
            "degrees_of_freedom": problem.hamiltonian.n,
            "hamiltonian": str(problem.hamiltonian.H),
            "parameters": dict(problem.parameters),
            "q0": problem.q0,
            "p0": problem.p0,
        }
    out["settings"] = {**dict(settings or {}), "solve": dict(solution.options)}
    out.update(
        status=solution.status.name,
        success=solution.success,
        partial=solution.partial,
        message=solution.message,
        nodes=len(solution),
        t_final=float(solution.t[-1]) if len(solution) else None,
        stats=dict(solution.stats),
        wall_time_s=dict(wall_time or {}),
        diagnostics=None if diagnostics is None else diagnostics.to_dict(),
        notes=list(notes),
        versions=package_versions(),
    )
    if getattr(solution, "t_events", None) is not None:
        # Per event function: its roots, the states there and RKQ's bound
        # max(atol, rtol |y|) on each state's error (hamrkq.events).
        out["events"] = [
            {"label": label, "t": t, "y": y, "error_bound": bound}
            for label, t, y, bound in zip(
                solution.event_labels,
                solution.t_events,
                solution.y_events,
                solution.event_bound,
                strict=True,
            )
        ]
    return jsonable(out)


# -- the table on stdout ----------------------------------------------------------
def _num(value: Any, spec: str = ".3e") -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "n/a"
    return format(value, spec)


def summary_rows(
    solution: Any, diagnostics: Any, wall_time: float | None = None
) -> list[tuple[str, str]]:
    """The rows of the run summary: (label, text)."""
    sol, diag = solution, diagnostics
    stats = sol.stats
    rows = [
        ("method", sol.method),
        ("status", f"{sol.status.name}" + ("" if sol.success else " (partial results)")),
        ("nodes", f"{len(sol)} (t = {_num(sol.t[0], 'g')} .. {_num(sol.t[-1], 'g')})"),
        ("steps", f"{stats.get('steps', 0)} accepted, {stats.get('rejected', 0)} rejected"),
        ("quenches", str(stats.get("quenches", 0)) if sol.z is not None else "n/a (no RK8 track)"),
        ("f evaluations", str(stats.get("nfev", 0))),
    ]
    if wall_time is not None:
        rows.append(("wall time (solve)", f"{wall_time:.2f} s"))
    if diag is None:
        return rows
    if diag.estimated is not None:
        rows.append(("max est. global error", _components(diag.estimated)))
        rows.append(("  trajectory / bound", _num(diag.estimated.bound_ratio, ".4f")))
    if diag.error is not None and diag.error is not diag.estimated:
        label = f"max true error ({diag.error.source})"
        if diag.error_measured:
            # never a true error without the accuracy of what it is measured against
            accuracy = f"reference accurate to ~{_num(diag.error.reference_accuracy, '.1e')}"
            rows.append((label, f"{_components(diag.error)} ({accuracy})"))
            rows.append(("  trajectory / bound", _num(diag.error.bound_ratio, ".4f")))
        else:
            rows.append((label, diag.error_note))
    if diag.energy is not None and not diag.energy_conserved:
        rows.append(("energy", diag.energy_note))
    elif diag.energy is not None:
        rows.append(
            (
                "max |H - H(0)|",
                f"{_num(diag.energy.max_abs)} "
                f"(drift {_num(diag.energy.drift, '+.2e')} per unit t)",
            )
        )
        rows.append(("  energy / bound", _num(diag.energy_bound_ratio, ".4f")))
    for inv in diag.invariants:
        rows.append((f"max |{inv.name} - {inv.name}(0)|", _num(inv.max_abs)))
    if math.isfinite(diag.gamma_max):
        rows.append(("max |Gamma| (RK8 track)", _num(diag.gamma_max)))
    return rows


def _components(summary: Any) -> str:
    parts = ", ".join(
        f"{n} {_num(v)}" for n, v in zip(summary.names, summary.max_abs, strict=True)
    )
    return f"{parts}; trajectory {_num(summary.max_trajectory)}"


def format_table(rows: Iterable[tuple[str, str]]) -> str:
    """Two aligned columns."""
    rows = list(rows)
    width = max((len(label) for label, _ in rows), default=0)
    return "\n".join(f"{label:<{width}}  {text}" for label, text in rows)


# -- progress ----------------------------------------------------------------
class ProgressBar:
    """``progress(fraction, t)`` for :func:`hamrkq.solve`: a bar on a terminal.

    Nothing is drawn before ``delay`` seconds have passed (short runs stay
    quiet) or when ``stream`` is not a terminal (pipes, files, CI logs).

    Parameters
    ----------
    label : str
        Shown before the bar.
    stream : file, optional
        Default ``sys.stderr``.
    delay : float
        Seconds before the bar first appears.
    enabled : bool, optional
        Force the bar on or off; default: whether ``stream`` is a terminal.
    """

    def __init__(
        self,
        label: str,
        *,
        stream: TextIO | None = None,
        delay: float = 1.0,
        enabled: bool | None = None,
        width: int = 30,
    ):
        self.label = label
        self.stream = sys.stderr if stream is None else stream
        if enabled is None:
            isatty = getattr(self.stream, "isatty", None)
            enabled = bool(isatty and isatty())
        self.enabled = enabled
        self.delay = delay
        self.width = width
        self.start = time.monotonic()
        self.drawn = False

    def __call__(self, fraction: float, t: float) -> None:
        if not self.enabled:
            return
        elapsed = time.monotonic() - self.start
        if elapsed < self.delay:
            return
        fraction = min(max(fraction, 0.0), 1.0)
        filled = int(self.width * fraction)
        eta = elapsed * (1 - fraction) / fraction if fraction > 0 else float("nan")
        eta_text = f"{eta:5.0f} s left" if math.isfinite(eta) else ""
        bar = "#" * filled + "." * (self.width - filled)
        self.stream.write(
            f"\r{self.label} [{bar}] {fraction:6.1%}  t={t:<10.6g} {elapsed:5.0f} s {eta_text}"
        )
        self.stream.flush()
        self.drawn = True

    def close(self) -> None:
        """End the bar's line (if one was drawn)."""
        if self.drawn:
            self.stream.write("\n")
            self.stream.flush()
            self.drawn = False

    def __enter__(self) -> ProgressBar:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
