"""``python -m daq --config FILE`` (the service) and ``python -m daq replay FILE``."""

import sys

from daq.cli import main

if __name__ == "__main__":
    sys.exit(main())
