"""Ctrl-C's one line and exit status, shared by the console script (before the command line
has loaded) and :func:`vetica_cli.cli.main`.  Imports nothing heavy: it must load while the
rest is being interrupted."""

INTERRUPTED_EARLY = "interrupted before any output was written"


def interrupt_handled() -> None:
    """Tell CPython that no KeyboardInterrupt went unhandled.  CPython 3.11 sets a global flag
    when a KeyboardInterrupt leaves code run by ``exec`` of a string (dataclasses and
    namedtuples build their methods so, at import) even if it is caught later, and at exit
    then ends the process by SIGINT (status -2) instead of our exit status: 3 of 40 Ctrl-Cs in
    the first two seconds of ``python -m vetica_cli sweep`` did.  Where the flag cannot be
    reached (another interpreter): no change."""
    try:
        import ctypes

        ctypes.c_int.in_dll(ctypes.pythonapi, "_Py_UnhandledKeyboardInterrupt").value = 0
    except (ImportError, ValueError, AttributeError, OSError):
        pass
