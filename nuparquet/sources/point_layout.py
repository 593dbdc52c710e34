"""The nuScenes lidar point record, named once: a `.pcd.bin` holds these float32 values per point (the devkit's
`LidarPointCloud.from_file` reshapes to 5), the lidar_points dataset stores them as columns
(schemas/lidar_points.json) and `Dataset.points` returns them in this order. Light on purpose: the CLI's
`--lidar-columns` help quotes it."""

LIDAR_FIELDS = ("x", "y", "z", "intensity", "ring")
NUSCENES_LIDAR_COLUMNS = len(LIDAR_FIELDS)
