"""A converted directory's `manifest.json`: read (locally or through the object store) and checked."""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from nuparquet.dataset.storage import is_url, read_text
from nuparquet.errors import FormatError
from nuparquet.format import FORMAT_NAME, FORMAT_VERSION, MANIFEST


def load_manifest(path: str | os.PathLike, storage_options: Mapping[str, Any] | None = None) -> tuple[str, dict]:
    """(root, manifest) of the nuparquet output `path`: the root as a resolved local path or the URL without a
    trailing slash, and the checked manifest.

    Raises `FormatError` if `path` does not exist, is not a nuparquet output, or was written in another format
    version."""
    text_path = os.fspath(path)
    if is_url(text_path):
        root = text_path.rstrip("/")
        try:
            text = read_text(f"{root}/{MANIFEST}", storage_options)
        except Exception as exc:  # noqa: BLE001 - polars' object store errors (not found, denied, no route) vary
            reason = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
            raise FormatError(f"{root}: cannot read {MANIFEST} ({reason}); not a nuparquet output, or the "
                              "storage_options do not reach it?") from exc
    else:
        local = Path(text_path.removeprefix("file://")).expanduser()
        if not local.exists():
            raise FormatError(f"{local}: no such directory")
        if not local.is_dir():
            raise FormatError(f"{local}: not a directory (expected a nuparquet output directory)")
        if not (local / MANIFEST).is_file():
            raise FormatError(f"{local}: not a nuparquet output (no {MANIFEST}; create one with `nuparquet convert`)")
        root = str(local.resolve())
        try:
            text = (local / MANIFEST).read_text()
        except (UnicodeDecodeError, OSError) as exc:
            raise FormatError(f"{root}: {MANIFEST} cannot be read as text ({exc.__class__.__name__}); "
                              "the output is damaged: convert again") from exc
    try:
        manifest = json.loads(text)
    except json.JSONDecodeError as exc:
        raise FormatError(f"{root}: {MANIFEST} is not valid JSON ({exc})") from exc
    return root, check_manifest(manifest, root)


def check_manifest(manifest: Any, where: str) -> dict:
    if not isinstance(manifest, dict) or manifest.get("format") != FORMAT_NAME:
        raise FormatError(f"{where}: not a nuparquet output ({MANIFEST} does not say \"format\": \"{FORMAT_NAME}\")")
    version = manifest.get("format_version")
    if isinstance(version, bool) or not isinstance(version, int):  # JSON true is a Python int
        raise FormatError(f"{where}: {MANIFEST} has no integer format_version")
    if version > FORMAT_VERSION:
        raise FormatError(
            f"{where}: written in nuparquet format {version}, newer than this nuparquet reads ({FORMAT_VERSION}); "
            "upgrade nuparquet")
    if version < FORMAT_VERSION:
        raise FormatError(
            f"{where}: written in nuparquet format {version}, older than this nuparquet reads ({FORMAT_VERSION}); "
            "convert the dataroot again with `nuparquet convert --overwrite`")
    if not isinstance(manifest.get("datasets"), dict) or not manifest["datasets"]:
        raise FormatError(f"{where}: {MANIFEST} lists no datasets")
    return manifest
