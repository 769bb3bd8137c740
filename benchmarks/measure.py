"""Measuring helpers for ``benchmarks/run.py``: clocks, memory, subprocesses,
the machine's description, and the tolerance search that matches SciPy's true
error to hamrkq's.  Importing it makes a first use compile before it runs
(``HAMRKQ_COMPILE=wait``)."""

from __future__ import annotations

import json
import math
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
import tracemalloc
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

# Benchmarks time compiled runs: a first use with backend="auto" would
# otherwise start interpreted while helper processes compile
# (hamrkq.backends.background), and runs timed soon after it would be
# interpreted too.  Every benchmark that runs hamrkq in its own process
# imports this module; benchmarks/first_use.py sets the mode per process.
os.environ.setdefault("HAMRKQ_COMPILE", "wait")


# -- the machine -----------------------------------------------------------------


def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _memory_gb() -> float | None:
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemTotal:"):
                return int(line.split()[1]) / 1024**2
    except OSError:
        pass
    return None


def _version(name: str) -> str:
    try:
        from importlib.metadata import version

        return version(name)
    except Exception:  # not installed
        return "not installed"


def head_commit() -> str:
    """The checkout's short commit hash; in a ``git archive`` copy (run so
    that edits to the working tree do not reach a long benchmark), the
    archived commit named by ``HAMRKQ_BENCH_COMMIT``, with " (an archive)";
    empty outside both."""
    archived = os.environ.get("HAMRKQ_BENCH_COMMIT")
    if archived:
        return f"{archived} (an archive)"
    return subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                          text=True, cwd=ROOT, check=False).stdout.strip()  # fmt: skip


def machine() -> dict[str, Any]:
    """What the numbers were measured on."""
    load = os.getloadavg() if hasattr(os, "getloadavg") else (math.nan,) * 3
    return {
        "cpu": _cpu_model(),
        "cores": os.cpu_count(),
        "memory_gb": _memory_gb(),
        "os": f"{platform.system()} {platform.release()}",
        "python": platform.python_version(),
        "numpy": _version("numpy"),
        "scipy": _version("scipy"),
        "sympy": _version("sympy"),
        "numba": _version("numba"),
        "load_average": [round(x, 2) for x in load],
    }


# -- clocks and memory -------------------------------------------------------------


@dataclass
class Timing:
    """Wall-clock seconds of repeated calls; ``median`` is the claim."""

    seconds: list[float] = field(default_factory=list)

    @property
    def median(self) -> float:
        return statistics.median(self.seconds)

    @property
    def spread(self) -> str:
        return f"{min(self.seconds):.3g}-{max(self.seconds):.3g}"


def timed(call: Callable[[], Any], repeat: int) -> tuple[Timing, Any]:
    """Call ``repeat`` times; the wall-clock times and the last result."""
    timing = Timing()
    result = None
    for _ in range(repeat):
        started = time.perf_counter()
        result = call()
        timing.seconds.append(time.perf_counter() - started)
    return timing, result


def traced_peak(call: Callable[[], Any]) -> float:
    """Peak of memory allocated through Python's allocators (NumPy arrays
    included) during one call, in MB above what was allocated before it."""
    tracemalloc.start()
    try:
        tracemalloc.reset_peak()
        before, _ = tracemalloc.get_traced_memory()
        call()
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    return (peak - before) / 1e6


def python(
    code: str,
    *,
    cache: Path | None = None,
    timeout: float = 1800,
    env: dict[str, str] | None = None,
    cwd: Path | None = None,
) -> tuple[float, dict]:
    """Run ``code`` in a fresh interpreter; (wall seconds including the
    interpreter's start, the JSON object it printed last).  ``python -c``
    puts its working directory first on ``sys.path``, before ``PYTHONPATH``:
    to measure another checkout, run it in ``cwd`` away from this one."""
    environment = {**os.environ, "PYTHONPATH": str(ROOT), **(env or {})}
    if cache is not None:
        environment["HAMRKQ_CACHE_DIR"] = str(cache)
    started = time.perf_counter()
    done = subprocess.run(
        [sys.executable, "-c", code],
        env=environment,
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=timeout,
    )
    wall = time.perf_counter() - started
    if done.returncode != 0:
        raise RuntimeError(f"subprocess failed ({done.returncode}):\n{done.stderr[-3000:]}")
    lines = [line for line in done.stdout.splitlines() if line.startswith("{")]
    return wall, (json.loads(lines[-1]) if lines else {})


def rounds_at_checkouts(
    code: str, roots: list[Path], rounds: int, prefix: str
) -> list[list[dict]]:
    """Run ``code`` once per checkout and round, each checkout first on
    ``PYTHONPATH`` in a fresh interpreter with its own warm caches (warmed by
    a first round that is not counted), the checkouts in turn within each
    round so that a change in the machine's load touches them alike; the
    JSON object each printed, per checkout.  ``code`` must print ``"file"``,
    ``hamrkq.__file__``, which is checked to be the checkout's."""
    measured: list[list[dict]] = [[] for _ in roots]
    with tempfile.TemporaryDirectory(prefix=prefix) as tmp:
        caches = [Path(tmp) / f"cache-{k}" for k in range(len(roots))]

        def one_round(k: int) -> dict:
            env = {"PYTHONPATH": str(roots[k]), "HAMRKQ_COMPILE": "wait",
                   "NUMBA_CACHE_DIR": str(caches[k] / "numba")}  # fmt: skip
            caches[k].mkdir(exist_ok=True)
            # run in the cache folder: python -c would import the checkout
            # it is started in before PYTHONPATH's
            result = python(code, cache=caches[k], env=env, cwd=caches[k])[1]
            if not result["file"].startswith(str(roots[k])):
                raise RuntimeError(f"measured {result['file']}, not the checkout {roots[k]}")
            return result

        for k in range(len(roots)):
            one_round(k)  # warm the caches: compiles
        for _ in range(rounds):
            for k in range(len(roots)):
                measured[k].append(one_round(k))
    return measured


def rows_at_checkout(script: str, root: Path, flag: str) -> list[dict]:
    """The rows ``script`` prints (one JSON list, its last line) when run
    with ``flag`` against the checkout at ``root`` (first on ``PYTHONPATH``,
    and the working directory): a benchmark's ``--before CHECKOUT``."""
    env = {**os.environ, "PYTHONPATH": str(root)}
    done = subprocess.run([sys.executable, script, flag], env=env, cwd=root,
                          capture_output=True, text=True, check=True)  # fmt: skip
    return json.loads(done.stdout.splitlines()[-1])


def command(args: list[str], *, cache: Path | None = None, timeout: float = 600) -> float:
    """Wall seconds of a command line (interpreter start included)."""
    environment = {**os.environ, "PYTHONPATH": str(ROOT)}
    if cache is not None:
        environment["HAMRKQ_CACHE_DIR"] = str(cache)
    started = time.perf_counter()
    done = subprocess.run(args, env=environment, capture_output=True, text=True, timeout=timeout)
    wall = time.perf_counter() - started
    if done.returncode not in (0, 1):  # 1: the run failed but wrote its results
        raise RuntimeError(f"{' '.join(args)} failed ({done.returncode}):\n{done.stderr[-3000:]}")
    return wall


#: Appended to a subprocess script: prints its peak resident memory in MB.
RSS_TAIL = """
import json, resource
print(json.dumps({"peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                  **globals().get("EXTRA", {})}))
"""


# -- a benchmark's record ---------------------------------------------------------------


def stamp() -> str:
    """The current time, as the records write it."""
    return time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime())


def begin_record(rounds: int, **fields: Any) -> dict[str, Any]:
    """A benchmark's record: the machine, when it started, the rounds, ``fields``."""
    return {"machine": machine(), "started": stamp(), "rounds": rounds, **fields}


def end_record(results: dict[str, Any]) -> dict[str, Any]:
    """``results`` with when it finished and the load average then."""
    results["finished"] = stamp()
    results["load_average_end"] = machine()["load_average"]
    return results


def save_record(folder: Path, name: str, results: dict[str, Any], table: Callable) -> str:
    """Write ``name.json`` and ``name.md`` (``table(results)``) in ``folder``;
    print and return the table."""
    (folder / f"{name}.json").write_text(json.dumps(results, indent=1) + "\n")
    text = table(results)
    (folder / f"{name}.md").write_text(text + "\n")
    print(text)
    return text


# -- matching SciPy's true error to hamrkq's -----------------------------------------


@dataclass
class Match:
    """The tolerance at which a SciPy method reached the target true error."""

    tolerance: float
    error: float
    target: float
    tries: list[tuple[float, float]]
    converged: bool


def match_tolerance(
    error_at: Callable[[float], float],
    target: float,
    start: float,
    *,
    rel: float = 0.15,
    max_tries: int = 7,
) -> Match:
    """Search the tolerance ``s`` whose run has max true error ``target``.

    ``error_at(s)`` runs the method at tolerance ``s`` and returns its max true
    error.  The search is a secant method in log-log coordinates (the error
    of a method of order p behaves like ``s**(p/(p+1))``), stopping when the
    error is within ``rel`` of the target.  If no try lands that close, the
    loosest tolerance whose error is at or below the target is chosen, so
    SciPy is never credited with less accuracy than hamrkq delivered.
    """
    tries: list[tuple[float, float]] = []

    def attempt(s: float) -> float:
        err = error_at(s)
        tries.append((s, err))
        return err

    s0, e0 = start, attempt(start)
    s1 = start / 10 if e0 > target else start * 10
    e1 = attempt(s1)
    for _ in range(max_tries - 2):
        if abs(math.log(e1 / target)) <= math.log1p(rel):
            break
        if e1 > target and s1 < s0 and e1 > 0.8 * e0:
            break  # tighter tolerances no longer help: rounding dominates
        slope = math.log(e1 / e0) / math.log(s1 / s0) if s1 != s0 and e1 != e0 else 0.8
        slope = min(max(slope, 0.2), 2.0)  # guard against noise in the error
        s2 = s1 * math.exp(math.log(target / e1) / slope)
        s0, e0, s1, e1 = s1, e1, s2, attempt(s2)
    within = [t for t in tries if abs(math.log(t[1] / target)) <= math.log1p(rel)]
    if within:
        best = min(within, key=lambda t: abs(math.log(t[1] / target)))
    else:  # the loosest tolerance that is at least as accurate as hamrkq
        below = [t for t in tries if t[1] <= target]
        best = max(below, key=lambda t: t[0]) if below else min(tries, key=lambda t: t[1])
    return Match(best[0], best[1], target, tries, bool(within))


def integrator_label(row: dict[str, Any]) -> str:
    """A table row's integrator, marked where its run stopped before the end
    of the interval (its status, and the time it reached where the row
    keeps it): its time and error are then of the part it covered."""
    label = row["integrator"]
    if row.get("status", "SUCCESS") == "SUCCESS":
        return label
    where = f" at t = {row['t_last']:g}" if "t_last" in row else " before t_end"
    return f"{label} (**{row['status']}{where}**)"


def max_error(y: np.ndarray, reference: np.ndarray) -> float:
    """Largest absolute error of any component at any node."""
    return float(np.max(np.abs(np.asarray(y) - np.asarray(reference))))
