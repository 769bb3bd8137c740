"""``python -m hamrkq``: the command line."""

from hamrkq.cli import entry_point

entry_point()
