"""The ``vetica`` console script and ``python -m vetica_cli``: the command line of
:mod:`vetica_cli.cli`, imported inside the guard so that Ctrl-C while the modules load
(numpy, numba, pandas: about a second) ends with one line and exit 130, not a traceback."""

import sys

from .interrupt import INTERRUPTED_EARLY, interrupt_handled


def main():  # pragma: no cover - console script entry
    try:
        from . import cli
    except KeyboardInterrupt:  # before any command started: nothing has been written
        sys.stderr.write(INTERRUPTED_EARLY + "\n")
        interrupt_handled()
        sys.exit(130)
    cli.main()


if __name__ == "__main__":  # pragma: no cover
    main()
