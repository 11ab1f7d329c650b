"""User-facing errors: the CLI prints the message on one line and exits 2."""

from .config import ConfigError


class InputError(ValueError):
    """Bad input data (missing columns, corrupt file, ...); one-line message."""


USER_ERRORS = (ConfigError, InputError)
