"""numba's cache files carry checksums; a damaged one is removed, compiled again
and named in one warning (hamrkq.backends.numba_cache).

Before: a truncated, emptied or garbled ``.nbc`` or ``.nbi`` raised
``UnpicklingError``, ``EOFError``, ``RuntimeError`` (LLVM) or
``UnicodeDecodeError`` out of every later compile, so ``backend="auto"`` ran
the interpreted loop for good, ``backend="numba"`` raised OptionError and
``hamrkq compile`` ended in a traceback; a flipped bit in the machine code
was loaded and run.  The first tests use a small function compiled into a
directory of their own; the last ones the step kernel and a catalogue
system, in fresh processes with a cache of their own (the session's is
shared by the other tests).
"""

from __future__ import annotations

import json
import math
import os
import pickle
import shutil
import subprocess
import sys
import textwrap
import time
import warnings
from pathlib import Path

import pytest

numba = pytest.importorskip("numba")

from hamrkq.backends import compiled, numba_cache  # noqa: E402
from hamrkq.backends import kernel as kernel_module  # noqa: E402
from hamrkq.backends.numba_compile import BackendUnavailable, jit  # noqa: E402
from hamrkq.errors import HamrkqWarning  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]

pytestmark = [
    pytest.mark.skipif(not compiled.available()[0], reason="compiled backend unavailable"),
    pytest.mark.skipif(not numba_cache.applicable(), reason="numba's cache laid out otherwise"),
]


def _sample(x):
    total = 0.0
    for i in range(1, 6):
        total += math.sin(x * i) / i
    return total


def _expected(x: float) -> float:
    return sum(math.sin(x * i) / i for i in range(1, 6))


def _compile(cache: Path, signature=None):
    return jit(_sample, signature or numba.float64(numba.float64), cache_dir=str(cache))


def _count(dispatcher, what: str) -> int:
    return sum(getattr(dispatcher.stats, what).values())


def _files(cache: Path, suffix: str) -> list[Path]:
    return sorted(cache.rglob(f"*{suffix}"))


def _garbled(raw: bytes) -> bytes:
    middle = len(raw) // 2
    return raw[:middle] + bytes(b ^ 0xA5 for b in raw[middle : middle + 64]) + raw[middle + 64 :]


def _bit_flipped(raw: bytes) -> bytes:
    middle = len(raw) // 2
    return raw[:middle] + bytes([raw[middle] ^ 0x10]) + raw[middle + 1 :]


DAMAGES = {
    "truncated": lambda raw: raw[: len(raw) // 2],
    "empty": lambda raw: b"",
    "garbled": _garbled,
    # Before: in the machine code, loaded and run without a word.
    "one bit flipped": _bit_flipped,
    "last byte cut": lambda raw: raw[:-1],
}


def _hamrkq_warnings(caught) -> list[str]:
    return [str(w.message) for w in caught if issubclass(w.category, HamrkqWarning)]


@pytest.mark.parametrize("suffix", [".nbc", ".nbi"])
@pytest.mark.parametrize("damage", DAMAGES)
def test_a_damaged_file_is_compiled_again_with_one_warning_naming_it(tmp_path, suffix, damage):
    first = _compile(tmp_path)
    assert first(0.7) == _expected(0.7) and _count(first, "cache_misses") == 1
    (path,) = _files(tmp_path, suffix)
    path.write_bytes(DAMAGES[damage](path.read_bytes()))

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        again = _compile(tmp_path)
    messages = _hamrkq_warnings(caught)
    assert len(messages) == 1, messages
    assert str(path) in messages[0] and "is damaged" in messages[0]
    assert "compiled it again" in messages[0]
    assert caught[0].filename == __file__  # the warning points at the caller
    assert _count(again, "cache_misses") == 1 and again(0.7) == _expected(0.7)

    # Saved whole again: the next load comes from the cache, silently.
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        third = _compile(tmp_path)
    assert _count(third, "cache_hits") == 1 and third(0.7) == _expected(0.7)


def _read_only(monkeypatch, cache: Path) -> None:
    """Make numba and hamrkq see ``cache`` as another user sees a shipped
    cache: readable, not writable (root writes anywhere, so chmod alone
    would not do it; QA ran the real thing as nobody)."""
    from numba.core import caching

    def inside(path) -> bool:
        return Path(path).resolve().is_relative_to(cache.resolve())

    writable = caching.UserProvidedCacheLocator.ensure_cache_path

    def ensure(self):
        if inside(self.get_cache_path()):
            raise PermissionError(f"{self.get_cache_path()}: read-only")
        writable(self)

    access = os.access
    monkeypatch.setattr(caching.UserProvidedCacheLocator, "ensure_cache_path", ensure)
    monkeypatch.setattr(
        os, "access", lambda path, mode, **kw: False if mode & os.W_OK and inside(path)
        else access(path, mode, **kw)
    )  # fmt: skip


def test_a_read_only_cache_folder_is_loaded_from_and_never_written(tmp_path, monkeypatch):
    # QA: numba passed over a cache folder it could not write (a cache made
    # by `hamrkq compile` and shipped read-only), compiled everything again
    # into ~/.cache/numba, or without a writable home found no cache and
    # hamrkq ran interpreted, blaming numba.
    first = _compile(tmp_path)
    assert _count(first, "cache_misses") == 1
    files = {p: p.stat().st_mtime_ns for p in tmp_path.rglob("*") if p.is_file()}
    _read_only(monkeypatch, tmp_path)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        again = _compile(tmp_path)
        # a signature the folder does not hold: compiled here, not kept
        other = _compile(tmp_path, numba.float64(numba.float32))
    assert _count(again, "cache_hits") == 1 and again(0.3) == _expected(0.3)
    assert _count(other, "cache_misses") == 1 and other(0.5) == pytest.approx(_expected(0.5))
    assert {p: p.stat().st_mtime_ns for p in tmp_path.rglob("*") if p.is_file()} == files
    (text,) = _hamrkq_warnings(caught)
    assert "is read-only" in text and "every process will compile it again" in text


def test_a_damaged_file_in_a_read_only_folder_is_said_once_not_to_be_kept(tmp_path, monkeypatch):
    """It said "compiled it again and cached the new code", then that the
    folder is read-only and nothing was kept (QA): one warning, true."""
    _compile(tmp_path)
    (data,) = _files(tmp_path, ".nbc")
    data.write_bytes(_garbled(data.read_bytes()))
    _read_only(monkeypatch, tmp_path)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        again = _compile(tmp_path)
    assert again(0.3) == pytest.approx(_expected(0.3), rel=1e-15)
    (text,) = _hamrkq_warnings(caught)
    assert "is damaged" in text and "the new code is not kept" in text, text
    assert "cached the new code" not in text


def test_every_file_ends_with_its_checksum_and_plain_numba_still_reads_it(tmp_path):
    _compile(tmp_path)
    files = _files(tmp_path, ".nbi") + _files(tmp_path, ".nbc")
    assert len(files) == 2
    for path in files:
        raw = path.read_bytes()
        body = raw[: -64 - len(numba_cache.CHECKSUM_MARK)]
        assert raw == numba_cache.sealed(body)
    # Unpickling ignores the bytes after the pickle: numba alone loads them.
    previous = numba.config.CACHE_DIR
    numba.config.CACHE_DIR = str(tmp_path)
    try:
        plain = numba.njit(numba.float64(numba.float64), cache=True)(_sample)
    finally:
        numba.config.CACHE_DIR = previous
    assert _count(plain, "cache_hits") == 1 and plain(0.3) == _expected(0.3)


def test_a_damaged_data_file_leaves_the_functions_other_signatures_alone(tmp_path):
    _compile(tmp_path)
    _compile(tmp_path, numba.float64(numba.int64))
    first, _ = _files(tmp_path, ".nbc")
    first.write_bytes(b"")
    with pytest.warns(HamrkqWarning, match="is damaged"):
        _compile(tmp_path)
    other = _compile(tmp_path, numba.float64(numba.int64))
    assert _count(other, "cache_hits") == 1


def test_a_damaged_index_takes_the_functions_data_files_with_it(tmp_path):
    """An unreadable index names no data file: they are removed with it, so
    numba, numbering new ones from 1, never reads a stale one under a new name."""
    _compile(tmp_path)
    _compile(tmp_path, numba.float64(numba.int64))
    assert len(_files(tmp_path, ".nbc")) == 2
    (index,) = _files(tmp_path, ".nbi")
    index.write_bytes(_garbled(index.read_bytes()))
    with pytest.warns(HamrkqWarning, match="index .* is damaged"):
        _compile(tmp_path)
    assert len(_files(tmp_path, ".nbc")) == 1
    other = _compile(tmp_path, numba.float64(numba.int64))  # compiled again: a plain miss
    assert _count(other, "cache_misses") == 1 and other(3) == _expected(3.0)


def test_an_index_naming_a_missing_data_file_is_a_miss_not_trusted(tmp_path):
    """numba's own reading: another process may be between writing the index
    and the data file.  Compiled again, without a warning."""
    _compile(tmp_path)
    (data,) = _files(tmp_path, ".nbc")
    data.unlink()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        again = _compile(tmp_path)
    assert _count(again, "cache_misses") == 1 and data.exists()


def test_checked_data_numba_cannot_rebuild_is_damaged_too(tmp_path):
    _compile(tmp_path)
    (data,) = _files(tmp_path, ".nbc")
    data.write_bytes(numba_cache.sealed(pickle.dumps(("not", "a compile result"))))
    with pytest.warns(HamrkqWarning, match="cannot be loaded") as caught:
        again = _compile(tmp_path)
    assert str(data) in str(caught[0].message)
    assert again(0.7) == _expected(0.7)


def test_a_failed_recompile_names_the_file_and_the_real_reason(tmp_path):
    _compile(tmp_path)
    (data,) = _files(tmp_path, ".nbc")
    data.unlink()
    data.mkdir()  # cannot be read, removed or written
    (data / "keep").write_text("")
    with pytest.raises(BackendUnavailable) as raised:
        _compile(tmp_path)
    message = str(raised.value)
    assert str(data) in message and "is damaged" in message
    assert "compiling it again failed (IsADirectoryError" in message


def test_a_file_another_process_has_written_again_is_not_removed(tmp_path):
    path = tmp_path / "f.1.nbc"
    path.write_bytes(b"damaged")
    _, identity = numba_cache._read(str(path))
    # Another process renames its freshly compiled file into place.
    time.sleep(0.01)
    (tmp_path / "new").write_bytes(numba_cache.sealed(b"fresh"))
    os.replace(tmp_path / "new", path)
    assert not numba_cache._remove(numba_cache.DamagedEntry(str(path), "x", identity))
    assert path.read_bytes() == numba_cache.sealed(b"fresh")
    _, identity = numba_cache._read(str(path))
    assert numba_cache._remove(numba_cache.DamagedEntry(str(path), "x", identity))
    assert not path.exists()


RACE = textwrap.dedent(
    """
    import json, sys, time, warnings
    from pathlib import Path
    import numba
    sys.path.insert(0, sys.argv[1])
    import sample
    from hamrkq.backends.numba_compile import jit
    go = Path(sys.argv[1]) / "go"
    while not go.exists():
        time.sleep(0.005)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        f = jit(sample.f, numba.float64(numba.float64), cache_dir=sys.argv[2])
    print(json.dumps({"value": f(0.7), "warnings": [str(w.message) for w in caught],
                      "hits": sum(f.stats.cache_hits.values())}))
    """
)


def test_two_processes_finding_the_same_damaged_file_both_run_and_leave_it_whole(tmp_path):
    source = tmp_path / "src"
    source.mkdir()
    (source / "sample.py").write_text(
        "import math\n\n\ndef f(x):\n    return sum([math.sin(x * i) / i for i in range(1, 6)])\n"
    )
    cache = tmp_path / "cache"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}

    def start() -> subprocess.Popen:
        command = [sys.executable, "-c", RACE, str(source), str(cache)]
        return subprocess.Popen(command, env=env, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True)  # fmt: skip

    def result(process: subprocess.Popen) -> dict:
        out, err = process.communicate(timeout=300)
        assert process.returncode == 0, err
        return json.loads(out.strip().splitlines()[-1])

    first = start()
    (source / "go").touch()
    assert result(first)["hits"] == 0
    (data,) = _files(cache, ".nbc")
    data.write_bytes(DAMAGES["truncated"](data.read_bytes()))
    (source / "go").unlink()
    racers = [start(), start()]
    time.sleep(1.0)  # both past their imports, waiting
    (source / "go").touch()
    results = [result(racer) for racer in racers]
    expected = _expected(0.7)
    assert all(abs(r["value"] - expected) < 1e-15 for r in results)
    damaged = [len([w for w in r["warnings"] if "is damaged" in w]) for r in results]
    assert max(damaged) == 1 and sum(damaged) >= 1, results
    last = result(start())
    assert last["hits"] == 1 and last["warnings"] == []


def test_an_unknown_cache_layout_leaves_numba_as_it_was(tmp_path, monkeypatch):
    monkeypatch.setattr(numba_cache, "applicable", lambda: False)
    f = _compile(tmp_path)
    assert f(0.7) == _expected(0.7)
    (data,) = _files(tmp_path, ".nbc")
    assert numba_cache.CHECKSUM_MARK not in data.read_bytes()


# -- the step kernel and a system, in fresh processes --------------------------------

SOLVE = textwrap.dedent(
    """
    import json, warnings
    import hamrkq
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        sol = hamrkq.solve(hamrkq.load_problem("harmonic"), t_span=(0.0, 10.0))
    print(json.dumps({"backend": sol.options["backend"], "t": sol.t.tolist(),
                      "y": sol.y.tolist(), "warnings": [str(w.message) for w in caught]}))
    """
)


def _environment(tmp_path: Path, kernel: Path) -> dict[str, str]:
    """A cache of its own holding a copy of ``kernel`` (a kernel folder)."""
    env = {**os.environ, "PYTHONPATH": str(ROOT), "HAMRKQ_COMPILE": "wait"}
    env["HAMRKQ_CACHE_DIR"] = str(tmp_path / "hamrkq")
    env["NUMBA_CACHE_DIR"] = str(tmp_path / "numba")
    env.pop(compiled.DISABLE_ENV, None)
    shutil.copytree(kernel, tmp_path / "hamrkq" / kernel.name)
    return env


def _solve(env: dict[str, str]) -> dict:
    done = subprocess.run([sys.executable, "-c", SOLVE], env=env, capture_output=True,
                          text=True, timeout=900)  # fmt: skip
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.strip().splitlines()[-1])


def _hamrkq(env: dict[str, str], *argv: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "hamrkq", *argv], env=env, capture_output=True,
                          text=True, timeout=900)  # fmt: skip


@pytest.fixture(scope="module")
def session_kernel() -> Path:
    """The session cache's kernel folder (compiled here if no test has yet)."""
    kernel_module.build_kernel()
    return kernel_module.kernel_cache_dir()


def test_damaged_system_files_are_compiled_again_and_a_failure_names_the_file(
    tmp_path, session_kernel
):
    env = _environment(tmp_path, session_kernel)
    done = _hamrkq(env, "compile", "harmonic")
    assert done.returncode == 0, done.stderr
    before = _solve(env)
    assert before["backend"] == "numba" and before["warnings"] == []
    numba_dir = tmp_path / "numba"
    (index,) = numba_dir.rglob("hamrkq_gen_*.rhs-*.nbi")
    (energy,) = numba_dir.rglob("hamrkq_gen_*.energy-*.nbc")
    index.write_bytes(_bit_flipped(index.read_bytes()))
    energy.write_bytes(DAMAGES["truncated"](energy.read_bytes()))

    done = _hamrkq(env, "compile", "harmonic")
    assert done.returncode == 0 and "Traceback" not in done.stderr, done.stderr
    assert done.stderr.count("is damaged") == 2
    assert str(index) in done.stderr and str(energy) in done.stderr
    assert "harmonic: compiled 2 function(s)" in done.stdout
    after = _solve(env)
    assert after == before  # compiled, silent, the same numbers

    # Compiling again fails (the file is a directory: it cannot be removed
    # or written): `hamrkq compile` exits 2 naming it, a run falls back to
    # the interpreted loop with the same reason.
    (rhs,) = numba_dir.rglob("hamrkq_gen_*.rhs-*.nbc")
    rhs.unlink()
    rhs.mkdir()
    (rhs / "keep").write_text("")
    done = _hamrkq(env, "compile", "harmonic")
    assert done.returncode == 2 and "Traceback" not in done.stderr, done.stderr
    assert done.stderr.startswith("hamrkq: error: ") and str(rhs) in done.stderr
    assert "compiling it again failed" in done.stderr
    fallback = _solve(env)
    assert fallback["backend"] == "python"
    (reason,) = fallback["warnings"]
    assert "is not used because" in reason and str(rhs) in reason
    assert fallback["y"] == before["y"]  # the interpreted loop: the same bits


@pytest.fixture(scope="module")
def kernel_alone(tmp_path_factory) -> Path:
    """A kernel folder compiled by ``build_kernel`` alone: ``loop.advance``
    for the one signature every run uses (the session's may hold more)."""
    root = tmp_path_factory.mktemp("kernel-alone")
    env = {**os.environ, "PYTHONPATH": str(ROOT), "HAMRKQ_CACHE_DIR": str(root)}
    env.pop(compiled.DISABLE_ENV, None)
    code = "from hamrkq.backends import kernel; kernel.build_kernel()"
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                          text=True, timeout=900)  # fmt: skip
    assert done.returncode == 0, done.stderr
    (folder,) = root.glob("kernel-*")
    return folder


@pytest.mark.slow
@pytest.mark.parametrize(
    "damage, how", [("truncated", "solve"), ("garbled", "hamrkq compile"), ("empty", "solve")]
)
def test_a_damaged_kernel_is_compiled_again_and_runs_compiled(tmp_path, kernel_alone, damage, how):
    """QA's report: the kernel's .nbc cut to half its size made every later run
    interpreted (100 times slower) and `hamrkq compile` end in a traceback."""
    env = _environment(tmp_path, kernel_alone)
    before = _solve(env)
    assert before["backend"] == "numba" and before["warnings"] == []
    (data,) = (tmp_path / "hamrkq").rglob("loop.advance-*.nbc")
    data.write_bytes(DAMAGES[damage](data.read_bytes()))

    if how == "solve":
        during = _solve(env)
        assert during["backend"] == "numba"
        assert (during["t"], during["y"]) == (before["t"], before["y"])
        (message,) = during["warnings"]
        assert str(data) in message and "compiled it again" in message
    else:
        done = _hamrkq(env, "compile")
        assert done.returncode == 0 and "Traceback" not in done.stderr, done.stderr
        assert done.stderr.count("is damaged") == 1 and str(data) in done.stderr
        assert "the step kernel: compiled 1 function(s)" in done.stdout
    after = _solve(env)
    assert after == before


def test_a_damaged_compiled_marker_is_rewritten_not_raised():
    """The marker that says a system's code is in numba's cache, garbled
    (bytes 0xff 0xfe), made every run end in UnicodeDecodeError's traceback
    (QA); it is read as absent and written again."""
    import numpy as np
    import sympy as sp

    import hamrkq
    from hamrkq.backends import codegen

    q, p = sp.symbols("q p", real=True)
    ham = hamrkq.Hamiltonian(p**2 / 2 + q**2 / 2 + q**4 / 977, q=[q], p=[p])  # its own files
    hamrkq.solve(ham, [1.0], [0.0], (0.0, 1.0), backend="numba")
    key = codegen.cache_key(ham)
    module = codegen.module_path(codegen.part_key(key, "system"))
    marker = module.with_suffix(compiled.COMPILED_SUFFIX)
    marker.write_bytes(b"\xff\xfe")
    assert compiled.is_compiled(ham) in (True, False)  # in this process it was compiled
    compiled.mark_compiled(module)
    assert marker.read_text() == compiled._numba_cache_setting()
    marker.write_bytes(b"\xff\xfe")
    sol = hamrkq.solve(ham, [1.0], [0.0], (0.0, 1.0), backend="numba")
    assert sol.success and np.isfinite(sol.y).all()


def test_a_cache_folder_that_cannot_be_used_compiles_without_a_cache(tmp_path):
    """A file where numba's subfolder of the kernel's cache folder belongs:
    numba fell back to the folder beside the function's source, and wrote the
    kernel's machine code into hamrkq's own package (QA).  Now the function
    is compiled without a cache, with one warning naming the folder, and
    nothing is written beside its source."""
    cache = tmp_path / "kernel-x"
    _compile(cache)
    (subfolder,) = [p for p in cache.iterdir() if p.is_dir()]
    shutil.rmtree(subfolder)
    subfolder.write_text("junk")
    beside = Path(__file__).parent / "__pycache__"
    before = sorted(beside.glob("*_sample*")) if beside.exists() else []
    with pytest.warns(HamrkqWarning, match=f"the cache folder {cache} cannot hold") as caught:
        dispatcher = _compile(cache)
    assert len(_hamrkq_warnings(caught)) == 1
    assert dispatcher(0.3) == pytest.approx(_expected(0.3), rel=1e-15)
    after = sorted(beside.glob("*_sample*")) if beside.exists() else []
    assert after == before and subfolder.read_text() == "junk"
