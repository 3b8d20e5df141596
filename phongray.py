"""``python -m phongray``: the same command as ``phongray``."""

import sys

from service.cli import main

if __name__ == "__main__":
    sys.exit(main())
