"""A converted dataset written back out: the nuScenes JSON files it was converted from, exactly
(`json_files.export_json`, the `export-json` command)."""
