"""``python -m canonid`` is the ``canonid`` command."""

import sys

from canonid.cli import main

sys.exit(main())
