"""``python -m canonid`` is the ``canonid`` command."""

import sys

from canonid.cli import main

if __name__ == "__main__":  # a worker process started by spawn imports this module too
    sys.exit(main())
