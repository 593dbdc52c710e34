"""The sensor data of a converted dataset: one reader for points, images and labels, deciding once whether a frame's
data comes from the Parquet (converted points, or the files embedded by `convert --embed`: `embedded`) or from
its file under the dataroot, and failing with one message when it is neither (`reader.SensorReader`,
`ds.sensors`); where the files are is `options.SensorFiles` (the one `--dataroot` flag)."""

from __future__ import annotations
