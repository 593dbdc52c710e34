"""The package's version, in one place below every layer that records it (the manifest, MCAP files, the CLI)."""

__version__ = "0.1.0"
