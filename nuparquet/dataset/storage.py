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
