"""The CAN bus expansion aligned to samples (numpy and polars; the files are read by `nuparquet.sources.can_bus`).

- `align`: per sample, the last message of each type at or before it (as-of join) with its age, and the
  continuous signals interpolated between the neighbouring messages.
- `bevformer`: the 18-value `can_bus` vector of the BEVFormer / UniAD / VAD data converters, exactly as they
  compute it, and the corrected vector beside it.
- `blacklists`: the devkit's lists of scenes with known CAN bus and localisation problems, as public data.
- `routes`: scenes whose poses stray from the baseline route (`list_misaligned_routes`).
"""
