"""The inputs of a conversion: one module per kind of source file, each with its own reader, reporting bad input
as `nuparquet.problems.Problem`s (file relative to the dataroot, record index, token). A source returns Arrow
tables; the builders in `nuparquet/conversion/builders/` turn them into datasets, and `export-json` writes each
converted JSON file back by the `kind` the manifest records for it (`nuparquet/export/json_files.py`).

- `tables` (+ `json_records`, `strict_json`, `table_types`, `table_layouts`, `table_diagnostics`): the JSON
  tables of the version folder, read with DuckDB; `integrity`: the checks across tables (keys, chains, counts).
- `points`: lidar `.pcd.bin` and radar `.pcd` files, lidarseg/panoptic label files.
- `can_bus`: the CAN bus expansion files; `map_expansion`: the map expansion files.
"""
