"""The explorer's renderers, drawn by `nuparquet.rendering.pictures.single` from the Parquet instead of matplotlib.

Each takes the devkit's arguments in the devkit's order and puts the picture where the devkit's figure went:
written to `out_path` (PNG or JPEG), drawn on `ax` (any matplotlib Axes: `ax.imshow`), else shown with
matplotlib when it is installed (the devkit's `plt.show()`; a no-op on a headless backend). Each also returns the
(H, W, 3) uint8 RGB picture, where the devkit returns None. The pictures are read from the converted data, not
from records a user changed in memory.

The scene videos (`render_scene*`, `render_ego_centric_map`) stay `nuparquet render`'s: the devkit plays them in
an OpenCV window, which a headless tool cannot open.
"""

from __future__ import annotations

import numpy as np

from nuparquet.devkit.errors import NotServed
from nuparquet.errors import UsageError

_WITH_DEVKIT = ("; with nuscenes-devkit installed, nuscenes.nuscenes.NuScenesExplorer(nusc).{name}(...) also "
                "accepts this object")


def _point_color(render_intensity: bool = False, show_lidarseg: bool = False, show_panoptic: bool = False) -> str:
    """The devkit's three colouring flags as the one point colour of `rendering.point_colors` (lidarseg wins
    over panoptic, as the devkit's `if show_lidarseg: ... elif show_panoptic` does; intensity with labels, which the
    devkit asserts against, is refused)."""
    if render_intensity and (show_lidarseg or show_panoptic):
        raise UsageError("colour by intensity or by labels, not both")
    return ("lidarseg" if show_lidarseg else "panoptic" if show_panoptic else
            "intensity" if render_intensity else "depth")


def _single():
    from nuparquet.rendering.pictures import single

    return single


def _place(image: np.ndarray, out_path=None, ax=None) -> np.ndarray:
    """Put `image` where the devkit's figure would go: the file `out_path`, the Axes `ax`, else a shown figure."""
    if ax is not None:
        ax.imshow(image)
        ax.axis("off")
    if out_path is not None:
        _single().save_image(image, out_path)
    elif ax is None:
        try:
            import matplotlib.pyplot as plt
        except ImportError:  # nothing to show on: the returned picture is the result
            return image
        plt.figure()
        plt.imshow(image)
        plt.axis("off")
        plt.show()
    return image


class ExplorerRenders:
    """`NuScenesExplorer.render_*` over `self.nusc` (a `nuparquet.devkit.NuScenes`)."""

    nusc: object

    @property
    def _ds(self):
        return self.nusc._dataset

    def render_sample_data(self, sample_data_token: str, with_anns: bool = True, box_vis_level="any",
                           axes_limit: float = 40, ax=None, nsweeps: int = 1, out_path: str | None = None,
                           underlay_map: bool = True, use_flat_vehicle_coordinates: bool = True,
                           show_lidarseg: bool = False, show_lidarseg_legend: bool = False,
                           filter_lidarseg_labels=None, lidarseg_preds_bin_path: str | None = None,
                           verbose: bool = True, show_panoptic: bool = False) -> np.ndarray:
        """A camera image with its boxes, or lidar / radar points from above."""
        image = _single().render_sample_data(
            self._ds, sample_data_token, with_anns=with_anns, box_vis_level=box_vis_level, axes_limit=axes_limit,
            nsweeps=nsweeps, underlay_map=underlay_map, use_flat_vehicle_coordinates=use_flat_vehicle_coordinates,
            point_color=_point_color(show_lidarseg=show_lidarseg, show_panoptic=show_panoptic),
            show_lidarseg_legend=show_lidarseg_legend, filter_lidarseg_labels=filter_lidarseg_labels,
            lidarseg_preds_bin_path=lidarseg_preds_bin_path)
        return _place(image, out_path, ax) if verbose or out_path is not None or ax is not None else image

    def render_sample(self, token: str, box_vis_level="any", nsweeps: int = 1, out_path: str | None = None,
                      show_lidarseg: bool = False, filter_lidarseg_labels=None,
                      lidarseg_preds_bin_path: str | None = None, verbose: bool = True,
                      show_panoptic: bool = False) -> np.ndarray:
        """Every sensor of a sample in one picture."""
        image = _single().render_sample(
            self._ds, token, box_vis_level=box_vis_level, nsweeps=nsweeps,
            point_color=_point_color(show_lidarseg=show_lidarseg, show_panoptic=show_panoptic),
            filter_lidarseg_labels=filter_lidarseg_labels, lidarseg_preds_bin_path=lidarseg_preds_bin_path)
        return _place(image, out_path) if verbose or out_path is not None else image

    def render_pointcloud_in_image(self, sample_token: str, dot_size: int = 5, pointsensor_channel: str = "LIDAR_TOP",
                                   camera_channel: str = "CAM_FRONT", out_path: str | None = None,
                                   render_intensity: bool = False, show_lidarseg: bool = False,
                                   filter_lidarseg_labels=None, ax=None, show_lidarseg_legend: bool = False,
                                   verbose: bool = True, lidarseg_preds_bin_path: str | None = None,
                                   show_panoptic: bool = False) -> np.ndarray:
        """A sample's lidar or radar points on one of its camera images."""
        image = _single().render_pointcloud_in_image(
            self._ds, sample_token, dot_size=dot_size, pointsensor_channel=pointsensor_channel,
            camera_channel=camera_channel, point_color=_point_color(render_intensity, show_lidarseg, show_panoptic),
            filter_lidarseg_labels=filter_lidarseg_labels, show_lidarseg_legend=show_lidarseg_legend,
            lidarseg_preds_bin_path=lidarseg_preds_bin_path)
        return _place(image, out_path, ax) if verbose or out_path is not None or ax is not None else image

    def render_annotation(self, anntoken: str, margin: float = 10, view: np.ndarray | None = None,
                          box_vis_level="any", out_path: str | None = None, extra_info: bool = False) -> np.ndarray:
        """An annotation in the lidar view beside the camera that sees it."""
        image = _single().render_annotation(self._ds, anntoken, margin, view, box_vis_level, extra_info)
        return _place(image, out_path)

    def render_instance(self, instance_token: str, margin: float = 10, view: np.ndarray | None = None,
                        box_vis_level="any", out_path: str | None = None, extra_info: bool = False) -> np.ndarray:
        """The instance's annotation nearest to the ego vehicle (the devkit's choice), as `render_annotation` draws it."""
        image = _single().render_instance(self._ds, instance_token, margin, view, box_vis_level, extra_info)
        return _place(image, out_path)

    # --- what `nuparquet render` does instead ------------------------------------------------------------------

    def render_egoposes_on_map(self, *args, **kwargs):
        raise NotServed("render_egoposes_on_map (the poses over the semantic prior PNG) is not served: "
                        "nuparquet.rendering.pictures.single.render_egoposes_on_map(OUT, location) draws them over the map "
                        "expansion (the map API's render_egoposes_on_fancy_map)"
                        + _WITH_DEVKIT.format(name="render_egoposes_on_map"))

    def render_scene(self, *args, **kwargs):
        raise NotServed("render_scene is not served: `nuparquet render OUT --scene NAME --channel all --out "
                        "scene.mp4` writes the scene's video" + _WITH_DEVKIT.format(name="render_scene"))

    def render_scene_channel(self, *args, **kwargs):
        raise NotServed("render_scene_channel is not served: `nuparquet render OUT --scene NAME --channel CAM_FRONT "
                        "--out scene.mp4` writes the channel's video"
                        + _WITH_DEVKIT.format(name="render_scene_channel"))

    def render_scene_channel_lidarseg(self, *args, **kwargs):
        raise NotServed("render_scene_channel_lidarseg is not served: `nuparquet render OUT --scene NAME --channel "
                        "CAM_FRONT --lidar --lidar-color lidarseg --out scene.mp4`"
                        + _WITH_DEVKIT.format(name="render_scene_channel_lidarseg"))

    def render_scene_lidarseg(self, *args, **kwargs):
        raise NotServed("render_scene_lidarseg is not served: `nuparquet render OUT --scene NAME --channel all --lidar "
                        "--lidar-color lidarseg --out scene.mp4`" + _WITH_DEVKIT.format(name="render_scene_lidarseg"))

    def render_ego_centric_map(self, *args, **kwargs):
        raise NotServed("render_ego_centric_map is not served: `nuparquet render OUT --scene NAME --channel bev` "
                        "draws the map about the ego vehicle" + _WITH_DEVKIT.format(name="render_ego_centric_map"))
