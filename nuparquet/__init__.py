"""nuparquet: nuScenes-format datasets as typed, denormalised Parquet."""

__version__ = "0.1.0"


def open(path):  # noqa: A001 - the public name users asked for: nuparquet.open(OUT)
    """Open a converted dataset directory (local path or fsspec/object-store URL); see `nuparquet.dataset`."""
    from nuparquet.dataset import open_dataset

    return open_dataset(path)
