"""Scenes as MCAP files for Foxglove: cameras, lidar and radar, transforms, boxes, the map and the CAN bus, in
Foxglove's published schemas (`nuparquet export-mcap`).

```python
import nuparquet
nuparquet.export_mcap("OUT", "scene-0061", out="scene-0061.mcap")       # or nuparquet.mcap.export_mcap
nuparquet.export_mcap_scenes("OUT", None, "mcap/", all_scenes=True)   # many, through the engine
```

Light on purpose: the writer (mcap, protobuf) loads on first use.
"""

from __future__ import annotations

from nuparquet.mcap.options import McapOptions

__all__ = ["McapOptions", "export_mcap", "export_scenes"]


def __getattr__(name: str):
    if name == "export_mcap":
        from nuparquet.mcap.export import export_mcap

        return export_mcap
    if name == "export_scenes":
        from nuparquet.mcap.batch import export_scenes

        return export_scenes
    raise AttributeError(f"module 'nuparquet.mcap' has no attribute {name!r}")
