"""nuscenes-devkit's `nuscenes.can_bus` package: `can_bus_api.NuScenesCanBus` over the converted CAN bus datasets."""
