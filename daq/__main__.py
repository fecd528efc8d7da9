"""``python -m daq COMMAND ...``: the same as the ``portal-daq`` console script."""

import sys

from daq.cli import main

if __name__ == "__main__":
    sys.exit(main())
