"""``python -m cfdesign``: the same as the ``cfdesign`` command."""

import sys

from .cli import console

sys.exit(console())
