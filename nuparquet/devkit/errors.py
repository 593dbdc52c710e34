"""What `nuparquet.devkit` refuses, and why: each error says which nuparquet call or command does the job."""

from __future__ import annotations

from nuparquet.errors import UsageError


class NotServed(UsageError, NotImplementedError):
    """A devkit call nuparquet does not answer (a renderer, a table that was not converted). The message names the
    nuparquet call or command that does it, or what to convert. A `NotImplementedError` too, so code that probes for
    optional devkit features keeps working."""


class ReadOnly(UsageError, TypeError):
    """A write to one of the tables: `nuparquet.devkit.NuScenes` serves the converted Parquet read-only."""
