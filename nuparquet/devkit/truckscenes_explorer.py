"""truckscenes-devkit's `TruckScenesExplorer` (`truckscenes.utils.visualization_utils`) over a
`nuparquet.devkit.truckscenes.TruckScenes`: its printers and scene filters, with the devkit's output and order; its
colormap (`truckscenes.utils.colormap.get_colormap`: `palette.TRUCKSCENES_RGB`, so that nuparquet never imports
the devkit).

Its renderers (matplotlib, OpenCV and Open3D in the devkit) are not served: each raises `NotServed` naming the
`nuparquet render` command that draws a TruckScenes sample or scene.
"""

from __future__ import annotations

from datetime import datetime, timezone

import numpy as np

from nuparquet.devkit.errors import NotServed
from nuparquet.rendering.palette import TRUCKSCENES_RGB

OPERATORS = {"<", ">", "<=", ">=", "==", "!="}
RENDERERS = ("render_pointcloud_in_image", "render_sample", "render_sample_data", "render_annotation",
             "render_instance", "render_scene", "render_scene_channel", "render_pointcloud",
             "render_calibrated_sensor")


def get_colormap() -> dict[str, tuple[int, int, int]]:
    """{class name: (r, g, b)}, a new dict on every call (callers may change it)."""
    return dict(TRUCKSCENES_RGB)


class TruckScenesExplorer:
    """The devkit's explorer over `trucksc` (a `TruckScenes`): the printers and filters; the renderers refused."""

    def __init__(self, trucksc):
        self.trucksc = trucksc

    def get_color(self, category_name: str) -> tuple[int, int, int]:
        return self.trucksc.colormap[category_name]

    def list_categories(self) -> None:
        """Each category's annotation count and mean ± std of width, length, height and length/width."""
        print("Category stats for split %s:" % self.trucksc.version)
        categories: dict[str, list] = {}
        for record in self.trucksc.sample_annotation:
            categories.setdefault(record["category_name"], []).append(
                record["size"] + [record["size"][1] / record["size"][0]])
        for name, stats in sorted(categories.items()):
            stats = np.array(stats)
            print(f"{name[:27]:27} n={stats.shape[0]:5}, "
                  f"width={np.mean(stats[:, 0]):5.2f}\u00B1{np.std(stats[:, 0]):.2f}, "
                  f"len={np.mean(stats[:, 1]):5.2f}\u00B1{np.std(stats[:, 1]):.2f}, "
                  f"height={np.mean(stats[:, 2]):5.2f}\u00B1{np.std(stats[:, 2]):.2f}, "
                  f"lw_aspect={np.mean(stats[:, 3]):5.2f}\u00B1{np.std(stats[:, 3]):.2f}")

    def list_attributes(self) -> None:
        """Each attribute's annotation count, by name."""
        counts: dict[str, int] = {}
        for record in self.trucksc.sample_annotation:
            for attribute_token in record["attribute_tokens"]:
                name = self.trucksc.get("attribute", attribute_token)["name"]
                counts[name] = counts.get(name, 0) + 1
        for name, count in sorted(counts.items()):
            print("{}: {}".format(name, count))

    def list_scenes(self) -> None:
        """The scenes by start time: name, length, annotations (the devkit's count leaves out the last sample's),
        description."""
        ts = self.trucksc

        def ann_count(record):
            count = 0
            sample = ts.get("sample", record["first_sample_token"])
            while not sample["next"] == "":
                count += len(sample["anns"])
                sample = ts.get("sample", sample["next"])
            return count

        recs = [(ts.get("sample", record["first_sample_token"])["timestamp"], record) for record in ts.scene]
        for _, record in sorted(recs, key=lambda r: r[0]):
            start_time = ts.get("sample", record["first_sample_token"])["timestamp"] / 1000000
            length_time = ts.get("sample", record["last_sample_token"])["timestamp"] / 1000000 - start_time
            desc = record["description"]
            if len(desc) > 55:
                desc = desc[:51] + "..."
            started = datetime.fromtimestamp(start_time, timezone.utc).strftime("%y-%m-%d %H:%M:%S")
            print("[{}] {}: length: {:.2f}s, #anns: {}, desc: {:16}".format(
                started, record["name"], length_time, ann_count(record), desc))

    def list_sample(self, sample_token: str) -> None:
        """The sample's keyframe sample_data (modality, channel) and annotations (category)."""
        sample_record = self.trucksc.get("sample", sample_token)
        print("Sample: {}\n".format(sample_record["token"]))
        for sd_token in sample_record["data"].values():
            sd_record = self.trucksc.get("sample_data", sd_token)
            print(f"sample_data_token: {sd_token}, mod: {sd_record['sensor_modality']}, "
                  f"channel: {sd_record['channel']}")
        print("")
        for ann_token in sample_record["anns"]:
            ann_record = self.trucksc.get("sample_annotation", ann_token)
            print(f"sample_annotation_token: {ann_record['token']}, category: {ann_record['category_name']}")

    def get_scenes_weather_annotations_filtered(self, conditions: list[tuple[str, str, float]]) -> list[str]:
        """Tokens of the scenes whose weather record meets every (field, operator, value) condition, in scene order;
        [] without weather annotations. '==' and '!=' compare within 1e-6, as the devkit's."""
        ts = self.trucksc
        if not len(ts.weather_annotation):
            return []
        valid_fields = set(ts.weather_annotation[0].keys()) - {"token"}
        for field, operator, value in conditions:
            assert field in valid_fields, f"Invalid field '{field}'. Valid fields: {valid_fields}"
            assert operator in OPERATORS, f"Invalid operator '{operator}'. Valid operators: {OPERATORS}"
            assert isinstance(value, (int, float)), f"Value must be numeric, got {type(value)}"

        def holds(field_value, operator: str, threshold) -> bool:
            if operator == "<":
                return field_value < threshold
            if operator == ">":
                return field_value > threshold
            if operator == "<=":
                return field_value <= threshold
            if operator == ">=":
                return field_value >= threshold
            if operator == "==":
                return abs(field_value - threshold) < 1e-6
            return abs(field_value - threshold) >= 1e-6

        matching = []
        for scene in ts.scene:
            weather = ts.get("weather_annotation", scene["weather_annotation_token"])
            if all(holds(weather[field], operator, value) for field, operator, value in conditions):
                matching.append(scene["token"])
        return matching

    def get_scenes_description_filtered(self, conditions: list[tuple[str, str]]) -> list[str]:
        """Tokens of the scenes whose description contains ('==') or lacks ('!=') every keyword, in scene order."""
        for keyword, operator in conditions:
            assert isinstance(keyword, str), f"Keyword must be string, got {type(keyword)}"
            assert operator in {"==", "!="}, f"Invalid operator '{operator}'. Valid operators: {{'==', '!='}}"
        matching = []
        for scene in self.trucksc.scene:
            description = scene["description"]
            if all((keyword in description) == (operator == "==") for keyword, operator in conditions):
                matching.append(scene["token"])
        return matching


def _not_served(name: str):
    def refuse(self, *args, **kwargs):
        raise NotServed(f"{name} is not served by nuparquet.devkit.truckscenes: `nuparquet render OUT --sample "
                        "TOKEN --out sample.png` draws a TruckScenes sample (its lidars, fused radars and camera "
                        "mosaic), `nuparquet render OUT --scene NAME --out scene.mp4` a scene's video; with "
                        f"truckscenes-devkit installed, its own TruckScenes(...).{name}(...) draws from the dataroot")

    refuse.__name__ = name
    refuse.__doc__ = f"truckscenes-devkit's {name}: not served (raises NotServed naming `nuparquet render`)."
    return refuse


for _name in RENDERERS:
    setattr(TruckScenesExplorer, _name, _not_served(_name))
