"""The `nuparquet` command line: thin wrappers that parse, show progress and print."""
