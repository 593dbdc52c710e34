"""Where a converted directory lives: a local folder or an object-store URL (`s3://`, `gs://`, `az://`, `hf://`,
`https://`), reached through polars' own object-store layer with one `storage_options` dict in polars' vocabulary
(`{"aws_endpoint_url": ..., "aws_access_key_id": ...}`, as `pl.scan_parquet` takes it). The manifest is read the
same way as every dataset (`pl.scan_lines`), so one dict serves both: no second client with other keys.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import polars as pl


def is_url(path: str) -> bool:
    return "://" in path and not path.startswith("file://")


def read_text(url: str, storage_options: Mapping[str, Any] | None) -> str:
    """The text of a small remote file (the manifest), read through polars with `storage_options`."""
    lines = pl.scan_lines(url, glob=False, storage_options=dict(storage_options) if storage_options else None)
    return "\n".join(lines.collect().to_series().to_list())


# polars' (object_store's) S3 keys -> pyarrow.fs.S3FileSystem's arguments: the same dict opens the files pyarrow
# reads itself (the row groups of one frame's points), so no second set of credentials exists.
_S3_KEYS = {
    "aws_access_key_id": "access_key", "access_key_id": "access_key",
    "aws_secret_access_key": "secret_key", "secret_access_key": "secret_key",
    "aws_session_token": "session_token", "session_token": "session_token", "aws_token": "session_token",
    "token": "session_token",
    "aws_region": "region", "region": "region", "aws_default_region": "region",
    "aws_endpoint_url": "endpoint", "aws_endpoint": "endpoint", "endpoint_url": "endpoint", "endpoint": "endpoint",
}


def arrow_filesystem(url: str, storage_options: Mapping[str, Any] | None):
    """(pyarrow FileSystem, path inside it) for a dataset URL, configured from the same `storage_options` (polars'
    keys) as the scans; S3 keys are translated (`_S3_KEYS`, `aws_allow_http`), other stores take their
    credentials from the environment as pyarrow reads them."""
    import pyarrow.fs as pafs

    scheme, _, rest = url.partition("://")
    if scheme in ("s3", "s3a"):
        kwargs: dict[str, Any] = {}
        for key, value in (storage_options or {}).items():
            target = _S3_KEYS.get(key.lower())
            if target is not None:
                kwargs[target] = str(value)
        endpoint = kwargs.pop("endpoint", None)
        if endpoint:
            endpoint_scheme, _, host = endpoint.partition("://")
            kwargs["endpoint_override"] = host or endpoint_scheme
            if host:
                kwargs["scheme"] = endpoint_scheme
        return pafs.S3FileSystem(**kwargs), rest
    filesystem, path = pafs.FileSystem.from_uri(url)
    return filesystem, path
