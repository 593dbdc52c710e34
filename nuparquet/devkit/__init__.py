"""nuscenes-devkit's `NuScenes`, served from a nuparquet output: existing devkit code runs unchanged.

```python
from nuparquet.devkit import NuScenes          # instead of: from nuscenes.nuscenes import NuScenes
nusc = NuScenes("v1.0-trainval", dataroot="/data/nuscenes", parquet="/data/nusc.parquet")
```

The import paths mirror the devkit's where user code imports from: `nuparquet.devkit.nuscenes` (`NuScenes`,
`NuScenesExplorer`), `nuparquet.devkit.utils.data_classes` (`Box`, `LidarPointCloud`, `RadarPointCloud`),
`...utils.geometry_utils` (`view_points`, `box_in_image`, `BoxVisibility`, `transform_matrix`, `points_in_box`),
`...utils.splits`, `...utils.color_map`, `...utils.map_mask`, `...utils.data_io`,
`nuparquet.devkit.can_bus.can_bus_api` (`NuScenesCanBus`, over the converted `can_bus/` datasets) and
`nuparquet.devkit.prediction` (`PredictHelper`, over the converted annotation and sample tables).
`nuparquet.devkit.truckscenes.TruckScenes` is truckscenes-devkit's `TruckScenes` over a converted MAN TruckScenes
output (the same machinery: its tables, `getclosest`, its `get_sample_data`; each class refuses the other's output).

A skin, not a second engine: the records come from the converted tables (`tables/<name>`), rebuilt exactly as
`json.load` gave them; which boxes a frame shows follows `nuparquet.frames.boxes`' rule; the batch visibility
pre-check is `nuparquet.geometry`; points and labels come from the dataroot's files or the converted
`lidar_points/` / `radar_points/`. Where a devkit object's numbers are the point (a `Box` moved into a sensor frame,
`view_points`, `transform_matrix`, a slerped rotation), the devkit's own small formulas are kept operation for
operation with pyquaternion, so the results are bit-identical to the devkit's.

The one-picture renderers (`render_sample_data`, `render_sample`, `render_pointcloud_in_image`,
`render_annotation`, `render_instance`) draw with `nuparquet.rendering.pictures.single` and write `out_path`, draw on `ax`
or show with matplotlib as the devkit does. Not served (each raises `NotServed` saying what does it): the scene
videos and `render_egoposes_on_map` (`nuparquet render`), tables that were not converted.
"""

from nuparquet.devkit.errors import NotServed, ReadOnly
from nuparquet.devkit.nuscenes import NuScenes, NuScenesExplorer
from nuparquet.devkit.truckscenes import TruckScenes

__all__ = ["NuScenes", "NuScenesExplorer", "NotServed", "ReadOnly", "TruckScenes"]
