"""Errors a user can act on. The CLI prints their message (no traceback) and exits with `exit_code`."""


class NuparquetError(Exception):
    exit_code = 1


class UsageError(NuparquetError):
    """Bad arguments or paths: exit code 2."""

    exit_code = 2


class InputError(NuparquetError):
    """The input dataset is malformed or inconsistent; the message names file, record and token."""


class FormatError(NuparquetError):
    """A directory is not a nuparquet output, or its format version is not supported."""


class QueryError(NuparquetError):
    """A SQL query that polars cannot plan or run (syntax error, unknown table or column): exit code 1."""


class EnvironmentFault(NuparquetError):
    """The machine refused a file operation (a read-only folder, a file where a folder should be, a full disk):
    one line naming the path and the reason, exit code 1."""
