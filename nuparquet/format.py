"""The on-disk format of a conversion: its name and version as written to manifest.json.

Kept free of heavy imports: `nuparquet.open` checks these before anything else is loaded.
"""

FORMAT_NAME = "nuparquet"
FORMAT_VERSION = 2  # bump when a column of schemas/ changes name, type or meaning (2: flat [9] intrinsics,
# file_index, dimension strings as dictionaries)
MANIFEST = "manifest.json"
