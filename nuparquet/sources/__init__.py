"""The inputs of a conversion: one module per kind of source file, each with its own reader, reporting bad input
as `nuparquet.problems.Problem`s (file relative to the dataroot, record index, token). A source returns Arrow
tables; the builders in `nuparquet/conversion/builders/` turn them into datasets, and `export-json` writes each
converted JSON file back by the `kind` the manifest records for it (`nuparquet/export/json_files.py`).

- `tables` (+ `table_scan` over the compiled `json_scan`, `table_typing`, `table_layouts`, `json_records`): the
  JSON tables of the version folder, read in one pass each; `integrity`: the checks across tables (keys, chains,
  counts).
- `points`: lidar `.pcd.bin` and radar `.pcd` files, lidarseg/panoptic label files.
- `can_bus`: the CAN bus expansion files; `map_expansion`: the map expansion files.
"""
