"""The ``vetica`` console script and ``python -m vetica_cli``: the command line of
:mod:`vetica_cli.cli`, imported inside the guard so that Ctrl-C while the modules load
(numpy, typer; numba and pyarrow with the commands that need them) ends with one line and
exit 130, not a traceback.  BLAS and OpenMP are capped at one thread before numpy loads,
unless the user set their threads (:func:`vetica_cli.batch.launch.cap_blas_threads`)."""

import sys

from .batch.launch import cap_blas_threads
from .interrupt import INTERRUPTED_EARLY, interrupt_handled


def main():  # pragma: no cover - console script entry
    cap_blas_threads()  # before numpy loads BLAS: every command computes on one thread, as its workers do
    try:
        from . import cli
    except KeyboardInterrupt:  # before any command started: nothing has been written
        sys.stderr.write(INTERRUPTED_EARLY + "\n")
        interrupt_handled()
        sys.exit(130)
    cli.main()


if __name__ == "__main__":  # pragma: no cover
    main()
