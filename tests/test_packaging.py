"""What an installation ships: every package of the source tree.

pyproject.toml lists hamrkq's packages by name (the catalogue is mapped in
from problems/), so a new subpackage left out of the list is missing from a
non-editable install alone: the clean checkout's CI, which installs the
package, failed with "No module named 'hamrkq.events'" after events.py became
a package, while every test passed in the editable development install.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_every_subpackage_is_listed_for_installation():
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())
    listed = set(config["tool"]["setuptools"]["packages"])
    found = {
        ".".join(init.parent.relative_to(ROOT).parts)
        for init in (ROOT / "hamrkq").rglob("__init__.py")
        if "__pycache__" not in init.parts
    }
    assert found - listed == set(), "add them to [tool.setuptools] packages"
    assert "hamrkq.problems" in listed  # problems/, mapped in as a package
