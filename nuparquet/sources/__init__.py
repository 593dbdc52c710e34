"""The inputs of a conversion, one module per kind of source file, each with its own reader and problems:

- `tables`: the JSON tables of the version folder (one JSON array per table), read with DuckDB.

Coming beside it (each reports through `nuparquet.problems.Problem`, with `file` relative to the dataroot):
sensor files and per-point label files (`samples/`, `sweeps/`, `lidarseg/`, `panoptic/`), CAN bus message files
(`can_bus/scene-XXXX_<message>.json`), map expansion files (`maps/expansion/<location>.json`). A source returns
Arrow tables; the builders in `nuparquet/convert/builders/` turn them into datasets, and `export-json` writes
each converted JSON file back by the `kind` the manifest records for it (`nuparquet/export.py`).
"""
