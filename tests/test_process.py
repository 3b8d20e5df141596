"""Running one command to its end (service.programs.process): the end of its standard error kept however much
it writes, the flood beyond it discarded without being read."""

import subprocess
import sys

from service.programs.process import FREE_BYTES, _Tail

#: 40 MiB of noise in 1 MiB writes, then the line that matters
FLOOD = "import os\nfor _ in range(40):\n    os.write(2, b'e' * (1 << 20))\nos.write(2, b'\\nthe last words\\n')\n"


def test_the_end_of_a_flood_of_standard_error_is_kept():
    writer = subprocess.Popen([sys.executable, "-c", FLOOD], stderr=subprocess.PIPE)
    tail = _Tail(4096)
    assert writer.stderr is not None
    tail.read(writer.stderr)
    writer.wait()
    assert tail.data.endswith(b"e\nthe last words\n") and len(tail.data) == 4096
    assert tail.seen == 40 * (1 << 20) + len(b"\nthe last words\n") > FREE_BYTES  # (all of it drained)
