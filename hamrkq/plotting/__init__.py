"""Figures: the paper's Figures 1-4 (matplotlib, imported lazily by callers)."""

from hamrkq.plotting.figures import *  # noqa: F403
from hamrkq.plotting.figures import __all__  # noqa: F401
