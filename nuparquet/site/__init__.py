"""A converted dataset as a static web site (`nuparquet report`): facts, statistics tables and charts, a scene
table that sorts and filters, one page per scene with its video, keyframe renderings and CAN bus plots. Opens
from disk with no network.

```python
from nuparquet.site import ReportOptions, build_report
build_report("OUT", None, "report", ReportOptions(stills=2))   # every scene; a SceneSelection for fewer
```
"""

from __future__ import annotations

from nuparquet.site.options import ReportOptions

__all__ = ["ReportOptions", "build_report"]


def __getattr__(name: str):
    if name == "build_report":
        from nuparquet.site.build import build_report

        return build_report
    raise AttributeError(f"module 'nuparquet.site' has no attribute {name!r}")
