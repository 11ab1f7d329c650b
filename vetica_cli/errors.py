"""User-facing errors: the CLI prints the message on one line and exits 2.

Both are raised before any work starts where possible (STYLE: validate once, at
the boundary); kernels only assume.
"""


class ConfigError(ValueError):
    """A configuration problem; the message is one line naming the key, the value
    and what is allowed."""


class InputError(ValueError):
    """Bad input data (missing columns, corrupt file, ...); one-line message."""


USER_ERRORS = (ConfigError, InputError)
