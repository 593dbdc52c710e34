"""The devkit's `nuscenes.utils` modules that user code imports from, over nuparquet (see `nuparquet.devkit`)."""
