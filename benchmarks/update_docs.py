"""Copy the tables of the latest benchmark runs into ``docs/performance.md``.

    python benchmarks/update_docs.py

Replaces the text between ``<!-- NAME:begin -->`` and ``<!-- NAME:end -->``
markers in ``docs/performance.md`` with tables built from

- ``benchmarks/peers.json`` (``benchmarks/peers.py``): ``peers``;
- ``benchmarks/startup_before.json``, ``benchmarks/startup.json``,
  ``benchmarks/startup_rebased.json`` and ``benchmarks/startup_now.json``
  (``benchmarks/startup.py`` on the checkout before this round's changes,
  with them on the same step kernel, rebased on the rewritten kernel, and
  after the kernel's reference counting was removed, ``import hamrkq`` made
  lazy and the warm-up run once per system), and
  ``benchmarks/startup_kernel_fix.json`` (that last run, kept when the
  quencher's floor work and the remembered function addresses became
  "now"): ``startup``;
- ``benchmarks/nbody_rhs.json`` and ``benchmarks/nbody_rhs_before.json``
  (``benchmarks/nbody_rhs.py``): ``nbody``;
- ``benchmarks/first_use.json`` (``benchmarks/first_use.py``): ``first_use``, and
  ``benchmarks/first_use_helpers.json`` (its ``--helpers``): ``first_use_helpers``;
- ``benchmarks/cli_warm.json`` (``benchmarks/cli_warm.py``, checkouts side by
  side): ``cli``;
- ``benchmarks/kernel_compile.json`` (``benchmarks/kernel_compile.py``):
  ``kernel_compile``;
- ``benchmarks/lazy_functions.json`` (``benchmarks/lazy_functions.py``):
  ``lazy_functions``.

No number in those blocks is typed by hand.
"""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import peers  # noqa: E402

DOC = HERE.parent / "docs" / "performance.md"


def _load(name: str) -> dict | None:
    path = HERE / name
    return json.loads(path.read_text()) if path.exists() else None


def peers_block() -> str:
    results = _load("peers.json")
    if results is None:
        return "(run `python benchmarks/peers.py`)"
    m = results["machine"]
    head = (
        f"`benchmarks/peers.py --methods {' '.join(results['methods'])}`, run "
        f"{results['started']} to {results['finished']}"
        f"{' with --quick' if results['quick'] else ''}: {m['cpu']}, {m['cores']} cores, "
        f"load average {m['load_average']} at the start and {results['load_average_end']} "
        f"at the end; heyoka {results['heyoka']}, SciPy {m['scipy']}, numba {m['numba']}."
    )
    refs = [
        f"- {c['case']} (t in [{c['t_span'][0]:g}, {c['t_span'][1]:g}], compared on "
        f"{c['compared_on']}): {c['reference']['note']}."
        for c in results["cases"]
    ]
    return "\n".join([head, "", peers.table(results), "", peers.FOOTNOTE, "", *refs])


def startup_block() -> str:
    before, after = _load("startup_before.json"), _load("startup.json")
    rebased, now = _load("startup_rebased.json"), _load("startup_now.json")
    kernel_fix = _load("startup_kernel_fix.json")
    if after is None:
        return "(run `python benchmarks/startup.py`)"

    def get(results, path):
        value = results
        for key in path:
            if not isinstance(value, dict) or key not in value:
                return None
            value = value[key]
        return value

    def cell(results, wall, cpu, scale, unit, digits):
        if results is None:
            return "-"
        w, c = get(results, wall), get(results, cpu) if cpu else None
        text = "-" if w is None else f"{w * scale:.{digits}f} {unit}"
        return text if c is None else f"{text} ({c * scale:.{digits}f} {unit} CPU)"

    rows = [
        ("first call, empty cache, prentice2011 (`solve`, fresh process)",
         ("first_call_prentice2011", "solve"), ("first_call_prentice2011", "solve_cpu"),
         1.0, "s", 2, "<= 3 s"),
        ("first call, empty cache, outer_solar_system (`solve`, fresh process)",
         ("first_call_outer_solar_system", "solve"),
         ("first_call_outer_solar_system", "solve_cpu"), 1.0, "s", 2, "<= 10 s"),
        ("outer_solar_system, loop already cached (`solve`)",
         ("new_system_outer_solar_system", "solve"),
         ("new_system_outer_solar_system", "solve_cpu"), 1.0, "s", 2, ""),
        ("`import hamrkq`", ("first_call_prentice2011", "import"),
         ("first_call_prentice2011", "import_cpu"), 1.0, "s", 2, ""),
        ("per call, cached tiny problem (`solve` of harmonic, 5 nodes, median)",
         ("overhead", "solve_problem_ms"), ("overhead", "solve_problem_cpu_ms"),
         1.0, "ms", 3, "<= 0.3 ms"),
        ("cache key, same Hamiltonian object", ("overhead", "cache_key_ms"), None,
         1e3, "us", 1, ""),
        ("`hamrkq run prentice2011 --no-plots`, fresh process, warm cache (median)",
         ("cli_warm", "median"), ("cli_warm", "median_cpu"), 1.0, "s", 2, "<= 1.2 s"),
    ]  # fmt: skip
    lines = [
        "| what | before this round | this round's changes, same kernel | "
        "rebased on the new kernel | kernel fix | now | target |",
        "|---|---|---|---|---|---|---|",
    ]
    for label, wall, cpu, scale, unit, digits, target in rows:
        cells = [
            cell(r, wall, cpu, scale, unit, digits)
            for r in (before, after, rebased, kernel_fix, now)
        ]
        lines.append(f"| {label} | {' | '.join(cells)} | {target} |")
    parts = (("load_problem", "parse the problem file"),
             ("derive_rhs", "Hamilton's equations (SymPy)"),
             ("derive_jacobian", "the 36 x 36 Jacobian (SymPy)"),
             ("generate_source", "scalar source (`codegen.generate_source`)"),
             ("compile_rhs", "numba: rhs"), ("compile_jac", "numba: jac"),
             ("compile_rhs_jvp", "numba: rhs_jvp"), ("compile_energy", "numba: energy"),
             ("compile_energy_rows", "numba: energy_rows"),
             ("numeric_construct", "`numeric_of(ham)` (eager lambdify before)"))  # fmt: skip
    lines += [
        "",
        "outer_solar_system's system, step by step (CPU seconds, fresh process):",
        "",
        "| step | before this round | this round's changes | rebased | kernel fix | now |",
        "|---|---|---|---|---|---|",
    ]
    for key, label in parts:
        cells = [cell(r, ("breakdown_outer_solar_system", key), None, 1.0, "s", 2)
                 for r in (before, after, rebased, kernel_fix, now)]  # fmt: skip
        lines.append(f"| {label} | {' | '.join(cells)} |")
    note = "Wall time, and in parentheses the CPU time of the process where measured."
    runs = (("Before", before), ("Same kernel", after), ("Rebased", rebased),
            ("Kernel fix", kernel_fix), ("Now", now))  # fmt: skip
    for tag, results in runs:
        if results is not None:
            note += (
                f"  {tag}: {results['label'] or results['root']}, {results['started']}, "
                f"load average {results['machine']['load_average']} at the start and "
                f"{results.get('load_average_end', '-')} at the end."
            )
    return "\n".join([*lines, "", note])


def nbody_block() -> str:
    after, before = _load("nbody_rhs.json"), _load("nbody_rhs_before.json")
    if after is None:
        return "(run `python benchmarks/nbody_rhs.py`)"
    lines = ["| outer_solar_system, numba | before | now |", "|---|---|---|"]
    for label in after["ns_per_call"]:
        b = f"{before['ns_per_call'][label]:.0f} ns" if before else "-"
        lines.append(f"| {label}, per call | {b} | {after['ns_per_call'][label]:.0f} ns |")
    for label in after["compile_seconds"]:
        b = f"{before['compile_seconds'][label]:.2f} s" if before else "-"
        lines.append(
            f"| compile {label} (no cache) | {b} | {after['compile_seconds'][label]:.2f} s |"
        )
    for key, label in (("pow_calls_in_source", "`**` (pow) in the generated module"),
                       ("sqrt_calls_in_source", "`math.sqrt` in the generated module"),
                       ("source_lines", "lines of the generated module")):  # fmt: skip
        b = str(before[key]) if before else "-"
        lines.append(f"| {label} | {b} | {after[key]} |")
    loads = f"before {before['load_average']}, " if before else ""
    lines.append(
        f"\nGenerated and hand-written rhs agree to "
        f"{after['max_relative_difference_generated_vs_hand']:.1e} (relative to the largest "
        f"component).  Load average during the runs: {loads}now {after['load_average']}."
    )
    return "\n".join(lines)


def memory_block() -> str:
    results = _load("memory.json")
    if results is None:
        return "(run `python benchmarks/memory.py`)"
    import memory

    machine = results["machine"]
    return "\n".join([
        memory.table(results),
        "",
        f"Peak resident set size above an interpreter that loaded the same code and ran one "
        f"short solve ({results['interpreter_mb']:.1f} MB); {results['started']}, "
        f"{machine['cpu']}, {machine['cores']} cores, load average {machine['load_average']}.",
    ])  # fmt: skip


def cli_block() -> str:
    results = _load("cli_warm.json")
    if results is None:
        return "(run `python benchmarks/cli_warm.py --root BEFORE --root .`)"
    import cli_warm

    m = results["machine"]
    return f"{cli_warm.table(results)} {m['cpu']}, {m['cores']} cores."


def _tabled(json_name: str, module_name: str, table: str, command: str):
    """A block: ``module_name.table`` of ``json_name``, or how to make it."""

    def block() -> str:
        results = _load(json_name)
        if results is None:
            return f"(run `{command}`)"
        module = __import__(module_name)
        return getattr(module, table)(results)

    return block


first_use_block = _tabled("first_use.json", "first_use", "table", "python benchmarks/first_use.py")
first_use_helpers_block = _tabled(
    "first_use_helpers.json",
    "first_use",
    "helpers_table",
    "python benchmarks/first_use.py --helpers",
)
kernel_compile_block = _tabled(
    "kernel_compile.json", "kernel_compile", "table", "python benchmarks/kernel_compile.py"
)
lazy_functions_block = _tabled(
    "lazy_functions.json", "lazy_functions", "table", "python benchmarks/lazy_functions.py"
)


def main() -> int:
    text = DOC.read_text()
    for name, block in (("peers", peers_block), ("startup", startup_block),
                        ("memory", memory_block), ("nbody", nbody_block),
                        ("cli", cli_block), ("first_use", first_use_block),
                        ("first_use_helpers", first_use_helpers_block),
                        ("kernel_compile", kernel_compile_block),
                        ("lazy_functions", lazy_functions_block)):  # fmt: skip
        pattern = re.compile(rf"(<!-- {name}:begin -->).*?(<!-- {name}:end -->)", re.S)
        if not pattern.search(text):
            print(f"no <!-- {name}:begin/end --> markers in {DOC}", file=sys.stderr)
            return 1
        body = block()
        text = pattern.sub(lambda m, b=body: f"{m.group(1)}\n{b}\n{m.group(2)}", text)
    DOC.write_text(text)
    print(f"updated {DOC}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
