"""``python -m service.cli``: the ``phongray`` command."""

import sys

from service.cli import main

sys.exit(main())
