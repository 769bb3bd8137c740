"""Regenerate every number, output and table quoted in the docs from one run.

Usage (from the repository root)::

    python docs/generate.py            # run the pages, write docs/generated.json, fill the pages
    python docs/generate.py --check    # only check that the pages match docs/generated.json
    python docs/generate.py quickstart.md   # just one page

How a page says what is generated (Markdown, invisible when rendered):

- A fenced block right after a line ``<!-- output -->`` is the standard output
  of the runnable block before it (```` ```python ```` or ```` ```bash ````).
- ``<!-- gen:KEY -->TEXT<!-- /gen -->`` is a number or a table: ``KEY`` is
  computed by this script (:data:`FACTS`), from the page's own run.
- A runnable block after ``<!-- skip -->`` is not run (``pip install``, the
  45-second ``hamrkq reproduce``).

Every ``python`` block of a page runs, in order, in one fresh Python process
whose working directory is a new empty folder; every ``bash`` block runs with
``bash -e`` in the same folder, with this checkout first on ``PYTHONPATH``.  So
the code blocks are run exactly as a reader would paste them.

``docs/generated.json`` is the committed output of the last run.  The tests
(``tests/test_docs.py``) check that the pages match it, and rerun the pages and
compare: a change in the code's numbers that is not regenerated fails the
suite.  Wall times (``... 0.82 s``) are the one thing compared loosely.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
GENERATED = DOCS / "generated.json"
#: The pages this script runs and fills, in order.
PAGES = ("quickstart.md", "cli.md", "diagnostics.md", "catalogue.md")

FENCE = re.compile(r"^```(\w*)\s*$")
INLINE = re.compile(r"<!-- gen:([\w.-]+) -->(.*?)<!-- /gen -->", re.S)
SEPARATOR = "\x1e--- hamrkq docs block ---\x1e"
#: Wall times and other timings differ between runs: compared as "<time>".
TIMING = re.compile(r"\b\d+(\.\d+)? ?(s|ms)\b")


# -- reading a page ------------------------------------------------------------
def blocks(text: str) -> list[dict[str, Any]]:
    """The fenced blocks of a page: ``kind`` (info string), ``start``/``end``
    (line indices of the fences), ``body``, and ``mark`` (the HTML comment on
    the line before the fence: ``output``, ``skip`` or None)."""
    lines = text.split("\n")
    found, i = [], 0
    while i < len(lines):
        match = FENCE.match(lines[i])
        if not match:
            i += 1
            continue
        j = i + 1
        while j < len(lines) and lines[j].rstrip() != "```":
            j += 1
        before = lines[i - 1].strip() if i else ""
        mark = {"<!-- output -->": "output", "<!-- skip -->": "skip"}.get(before)
        body = "\n".join(lines[i + 1 : j])
        found.append({"kind": match.group(1), "start": i, "end": j, "body": body, "mark": mark})
        i = j + 1
    return found


def runnable(page_blocks: list[dict]) -> list[dict]:
    return [b for b in page_blocks if b["kind"] in ("python", "bash") and b["mark"] != "skip"]


# -- running a page --------------------------------------------------------------
def _environment() -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    env["PATH"] = os.pathsep.join([str(Path(sys.executable).parent), env.get("PATH", "")])
    env["MPLBACKEND"] = "Agg"
    env["COLUMNS"] = "100"  # argparse help wraps at this width
    return env


def run_page(name: str, workdir: Path) -> tuple[list[str], dict[str, Any]]:
    """Run the runnable blocks of a page in ``workdir``; returns the standard
    output of each (in order) and the namespace facts (:data:`FACTS`)."""
    text = (DOCS / name).read_text()
    todo = runnable(blocks(text))
    env = _environment()
    outputs: list[str] = []
    python = [b for b in todo if b["kind"] == "python"]
    py_out: list[str] = []
    facts: dict[str, Any] = {}
    if python or name in FACTS:
        # One process for the page's Python, so later blocks see earlier names.
        script = [f"print({SEPARATOR!r}, end='')\n" + b["body"] for b in python]
        script.append(f"print({SEPARATOR!r}, end='')\n" + _facts_code(name))
        path = workdir / "_page.py"
        path.write_text("\n".join(script) + "\n")
        result = subprocess.run(
            [sys.executable, str(path)], cwd=workdir, env=env, capture_output=True, text=True
        )
        path.unlink()
        if result.returncode != 0:
            raise RuntimeError(f"{name}: a python block failed:\n{result.stderr}")
        parts = result.stdout.split(SEPARATOR)[1:]
        py_out, facts = parts[:-1], json.loads(parts[-1] or "{}")
    for block in todo:
        if block["kind"] == "python":
            outputs.append(py_out.pop(0))
            continue
        result = subprocess.run(
            ["bash", "-e", "-o", "pipefail", "-c", block["body"]],
            cwd=workdir,
            env=env,
            capture_output=True,
            text=True,
        )
        if result.returncode != 0:
            raise RuntimeError(
                f"{name}: a bash block failed (status {result.returncode}):\n"
                f"{block['body']}\n{result.stderr}"
            )
        outputs.append(result.stdout)
    return outputs, facts


def _facts_code(name: str) -> str:
    """Python appended to a page's run that prints its facts as JSON."""
    body = FACTS.get(name)
    if body is None:
        return "print('{}')"
    return "import json as _json\n" + body + "\nprint(_json.dumps(facts))"


# -- the facts: numbers and tables quoted in the prose ---------------------------------
#: For each page, Python run after the page's own blocks (it sees their names)
#: that sets ``facts``: KEY -> text, filled into ``<!-- gen:KEY -->`` markers.
FACTS: dict[str, str] = {
    "quickstart.md": """
facts = {
    "n_nodes": f"{len(sol)}",
    "max_est": f"{abs(sol.global_error).max():.3e}",
    "ref_accuracy": f"{diag.error.reference_accuracy:.0e}",
    "gamma_max": f"{diag.gamma_max:.0e}",
    "true_over_est": f"{max(diag.error.max_abs) / max(diag.estimated.max_abs):.4f}",
    "rk34_factor": f"{max(d34.error.max_abs) / 1e-6:.0f}",
}
""",
    "catalogue.md": """
import hamrkq as _h
_rows = ["| name | n | title | invariants besides H | exact solution |", "|---|---|---|---|---|"]
for _name in _h.list_problems():
    _p = _h.load_problem(_name)
    _inv = ", ".join(f"`{k}`" for k in _p.invariants) or "-"
    _exact = "yes" if _p.exact_spec is not None else "-"
    _rows.append(f"| `{_name}` | {_p.hamiltonian.n} | {_p.title} | {_inv} | {_exact} |")
facts = {"catalogue_table": "\\n" + "\\n".join(_rows) + "\\n"}
""",
}


# -- filling a page ------------------------------------------------------------------
def fill(text: str, outputs: list[str], facts: dict[str, str]) -> str:
    """The page with its output blocks and ``gen`` markers set from a run.

    ``outputs`` are those of :func:`runnable` blocks in order; an output block
    takes the output of the nearest runnable block before it.
    """
    lines = text.split("\n")
    page_blocks = blocks(text)
    index = {id(b): k for k, b in enumerate(runnable(page_blocks))}
    last = None
    replacements = []
    for block in page_blocks:
        if id(block) in index:
            last = index[id(block)]
        if block["mark"] == "output":
            if last is None:
                raise ValueError(f"output block at line {block['start'] + 1} follows no code")
            replacements.append((block, outputs[last].rstrip("\n")))
    for block, body in reversed(replacements):
        lines[block["start"] + 1 : block["end"]] = body.split("\n") if body else []
    filled = "\n".join(lines)

    def inline(match: re.Match) -> str:
        key = match.group(1)
        if key not in facts:
            raise KeyError(f"no generated value for <!-- gen:{key} -->")
        return f"<!-- gen:{key} -->{facts[key]}<!-- /gen -->"

    return INLINE.sub(inline, filled)


def load() -> dict[str, Any]:
    return json.loads(GENERATED.read_text()) if GENERATED.exists() else {}


def normalise(text: str) -> str:
    """Output with its timings blanked (they differ from run to run)."""
    return TIMING.sub("<time>", text)


#: A number in an output: ``1.5e-09``, ``0.9325``, ``9835``, ``6.743001419250383``.
NUMBER = re.compile(r"[-+]?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?")
#: Errors and accuracies (below this, written in exponent form) are
#: compared within :data:`NOISE`: they are what a run measures against a
#: reference integrated by SciPy's DOP853, whose last bits depend on the
#: machine (NumPy's and BLAS's kernels for its CPU), and a true error is only
#: known to within its reference's accuracy.  The same checkout gave
#: "reference accurate to ~7.1e-12" on one machine and "~8.4e-12" on another,
#: a true error of 5.15e-10 and 5.28e-10 against a reference accurate to
#: 8e-11.  Other numbers must agree to :data:`DIGITS` (a period found by
#: Newton's method, 6.743001419250383 on one machine, ...384 on the other);
#: any number printed with fewer digits must be the same.
SMALL = 1e-6
NOISE = 0.25
DIGITS = 1e-12


def same_output(new: str, old: str) -> bool:
    """Whether two outputs say the same once normalised (:func:`normalise`): equal text
    between the numbers, equal numbers, and errors within :data:`NOISE`."""
    new, old = normalise(new), normalise(old)
    if NUMBER.split(new) != NUMBER.split(old):
        return False
    for a, b in zip(NUMBER.findall(new), NUMBER.findall(old), strict=True):
        if a == b:
            continue
        x, y = float(a), float(b)
        small = "e" in (a + b).lower() and max(abs(x), abs(y)) < SMALL
        if not abs(x - y) <= (NOISE if small else DIGITS) * max(abs(x), abs(y)):
            return False
    return True


def generate(pages: list[str]) -> dict[str, Any]:
    """Run ``pages``, write :data:`GENERATED` and fill the pages."""
    data = load()
    for name in pages:
        with tempfile.TemporaryDirectory(prefix="hamrkq-docs-") as folder:
            outputs, facts = run_page(name, Path(folder))
        data[name] = {"outputs": outputs, "facts": facts}
        path = DOCS / name
        path.write_text(fill(path.read_text(), outputs, facts))
        print(f"{name}: {len(outputs)} blocks run, {len(facts)} facts")
    GENERATED.write_text(json.dumps(data, indent=1, sort_keys=True) + "\n")
    return data


def check(pages: list[str]) -> list[str]:
    """Pages that differ from what :data:`GENERATED` says they should be."""
    data = load()
    stale = []
    for name in pages:
        text = (DOCS / name).read_text()
        entry = data.get(name)
        if entry is None or fill(text, entry["outputs"], entry["facts"]) != text:
            stale.append(name)
    return stale


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("pages", nargs="*", help=f"pages to run (default: {' '.join(PAGES)})")
    parser.add_argument("--check", action="store_true", help="only compare, run nothing")
    args = parser.parse_args(argv)
    pages = args.pages or list(PAGES)
    if args.check:
        stale = check(pages)
        for name in stale:
            print(f"docs/{name} does not match docs/generated.json: run python docs/generate.py")
        return 1 if stale else 0
    generate(pages)
    return 0


if __name__ == "__main__":
    sys.exit(main())
