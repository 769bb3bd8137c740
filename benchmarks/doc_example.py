"""Run one Python block of a docs page and print what it prints.

Usage: ``python benchmarks/doc_example.py docs/ensembles.md [INDEX]``
(INDEX: the page's Python blocks counted from 0; default 0).  The block runs
as written, in a fresh namespace; its printed lines are shown, each beside
the comment the page gives that line, so that the comments can be checked
against a run (the output is committed as ``benchmarks/doc_example_<page>.txt``,
e.g. ``python benchmarks/doc_example.py docs/ensembles.md >
benchmarks/doc_example_ensembles.txt``).
"""

from __future__ import annotations

import contextlib
import io
import re
import subprocess
import sys
import time
from pathlib import Path

FENCE = re.compile(r"^```(\w*)\s*$")


def python_blocks(text: str) -> list[list[str]]:
    """The page's ```python blocks, each as its lines."""
    found, body, inside = [], [], None
    for line in text.split("\n"):
        match = FENCE.match(line)
        if match and inside is None:
            inside, body = match.group(1), []
        elif line.strip() == "```" and inside is not None:
            if inside == "python":
                found.append(body)
            inside = None
        elif inside is not None:
            body.append(line)
    return found


def main() -> None:
    page = Path(sys.argv[1])
    index = int(sys.argv[2]) if len(sys.argv) > 2 else 0
    lines = python_blocks(page.read_text())[index]
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                            text=True, check=False).stdout.strip() or "unknown"  # fmt: skip
    out = io.StringIO()
    started = time.perf_counter()
    with contextlib.redirect_stdout(out):
        exec(compile("\n".join(lines), f"{page}:block{index}", "exec"), {"__name__": "__main__"})
    elapsed = time.perf_counter() - started
    comments = [line.split("#", 1)[1].strip() if "#" in line else "" for line in lines
                if line.lstrip().startswith("print(")]  # fmt: skip
    printed = out.getvalue().rstrip("\n").split("\n")
    print(f"{page}, Python block {index}, run at commit {commit} ({elapsed:.1f} s)")
    print("printed | the page's comment on that line")
    for i, text in enumerate(printed):
        comment = comments[i] if i < len(comments) else ""
        print(f"{text} | {comment}")


if __name__ == "__main__":
    main()
