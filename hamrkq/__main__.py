"""``python -m hamrkq``: the command line."""

import sys

from hamrkq.cli import main

sys.exit(main())
