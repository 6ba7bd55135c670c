"""The ``nephele`` command installed with the wheel: the library's command line (the code of
the ``nephele`` binary), run in this process."""

import signal
import sys

from ._nephele import main as _main


def main() -> None:
    """Run ``nephele`` with ``sys.argv`` and exit with its code."""
    # Ctrl-C ends the command as it ends the binary (Python's handler would wait for the
    # library to return).
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    sys.exit(_main(sys.argv))


if __name__ == "__main__":
    main()
