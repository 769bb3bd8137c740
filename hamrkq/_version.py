"""The version of hamrkq: its one home (``pyproject.toml`` reads it from here).

A literal rather than ``importlib.metadata.version("hamrkq")``: that lookup
imports the email parser and scans the installed distributions, about 20-30
ms of every ``import hamrkq`` (a command that builds a cache key still pays it
once, for numba's version: ``hamrkq.backends.codegen``).
"""

__version__ = "0.1.0"
