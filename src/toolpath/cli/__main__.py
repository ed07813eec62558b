"""``python -m toolpath.cli``: the same as the ``toolpath`` command."""

import sys

from toolpath.cli import main

sys.exit(main())
