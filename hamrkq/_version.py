"""The installed version of hamrkq (one place, importable from every layer)."""

from importlib.metadata import PackageNotFoundError
from importlib.metadata import version as _version

try:
    __version__ = _version("hamrkq")
except PackageNotFoundError:  # a source checkout that is not installed
    __version__ = "0.1.0"
