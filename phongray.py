"""``python -m phongray``: the same command as ``phongray``, from any folder.

``python -m`` puts the current folder first on the import path, so a student's ``tracer.py`` or ``service.py``
there would be imported instead of phongray's own modules.  The current folder is taken off the path first
(unless it is where this file lives: a source checkout).
"""

import os
import sys

if __name__ == "__main__":
    here = os.path.dirname(os.path.abspath(__file__))
    cwd = os.getcwd()
    sys.path[:] = [p for p in sys.path if os.path.abspath(p or ".") != cwd or cwd == here]

    from service.cli import main

    sys.exit(main())
