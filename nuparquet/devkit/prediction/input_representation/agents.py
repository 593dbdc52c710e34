"""The devkit's `input_representation.agents`: every agent of a sample drawn as its 2-D box over its recent past
(older boxes darker, the agent in the centre red), turned so that agent heads up, pixel for pixel as the devkit.

The records come from the helper (`get_past_for_sample`, `get_annotations_for_sample`); the boxes' yaws and
centre pixels are computed for all of them at once (`quaternion_yaws`, bit for bit pyquaternion's), their corners by
OpenCV's `boxPoints` and drawn by `fillPoly` one at a time in the devkit's order (a later box paints over an
earlier one). The rotation is asked for the agent's window only (`utils.rotate_and_crop`).
"""

from __future__ import annotations

import colorsys
from collections.abc import Callable
from typing import Any

import cv2
import numpy as np
from pyquaternion import Quaternion

from nuparquet.devkit.prediction.helper import quaternion_yaw, quaternion_yaws
from nuparquet.devkit.prediction.input_representation.interface import AgentRepresentation
from nuparquet.devkit.prediction.input_representation.utils import get_crops, pixel_coords, rotate_and_crop

History = dict[str, list[dict[str, Any]]]


def pixels_to_box_corners(row_pixel: int, column_pixel: int, length_in_pixels: float, width_in_pixels: float,
                          yaw_in_radians: float) -> np.ndarray:
    """(4, 2) float32 corners (column, row) of the box at (row, column) pixels, `length` along its heading."""
    # OpenCV's (x, y) is (column, row), and its positive angle turns clockwise on the image
    return cv2.boxPoints(((column_pixel, row_pixel), (length_in_pixels, width_in_pixels),
                          -yaw_in_radians * 180 / np.pi))


def track_boxes(annotations: list[dict[str, Any]], center_coordinates: tuple[float, float],
                center_pixels: tuple[float, float], resolution: float = 0.1) -> np.ndarray:
    """(N, 4, 2) float32 `get_track_box` of every annotation record."""
    if not annotations:
        return np.zeros((0, 4, 2), np.float32)
    assert resolution > 0
    translation = np.array([a['translation'][:2] for a in annotations], np.float64)
    size = np.array([a['size'][:2] for a in annotations], np.float64)
    angles = -quaternion_yaws(np.array([a['rotation'] for a in annotations], np.float64)) * 180 / np.pi
    rows, columns = pixel_coords(translation[:, 0], translation[:, 1], center_coordinates, center_pixels, resolution)
    # width and length swapped: the box is drawn along x, then turned
    widths, lengths = (size[:, 0] / resolution).tolist(), (size[:, 1] / resolution).tolist()
    return np.stack([cv2.boxPoints(((c, r), (length, width), angle)) for r, c, length, width, angle in
                     zip(rows.tolist(), columns.tolist(), lengths, widths, angles.tolist())])


def get_track_box(annotation: dict[str, Any], center_coordinates: tuple[float, float],
                  center_pixels: tuple[float, float], resolution: float = 0.1) -> np.ndarray:
    """(4, 2) float32 corners in pixels of an annotation's box in the image centred (row, column) `center_pixels`
    on global `center_coordinates`."""
    return track_boxes([annotation], center_coordinates, center_pixels, resolution)[0]


def reverse_history(history: History) -> History:
    """Each agent's records oldest first, so the newer boxes are drawn over the older."""
    return {token: anns[::-1] for token, anns in history.items()}


def add_present_time_to_history(current_time: list[dict[str, Any]], history: History) -> History:
    """`history` (reversed) with each present record appended to its instance's list (a new list for an instance
    without one); changes `history` in place and returns it."""
    for annotation in current_time:
        token = annotation['instance_token']
        if token in history:
            history[token].append(annotation)
        else:
            history[token] = [annotation]
    return history


def fade_color(color: tuple[int, int, int], step: int, total_number_of_steps: int) -> tuple[int, int, int]:
    """`color` darkened for an older step: HSV value from 0.4 at step 0 up to the colour's own at the last."""
    lowest_value = 0.4
    if step == total_number_of_steps:
        return color
    hsv_color = colorsys.rgb_to_hsv(*color)
    increment = (float(hsv_color[2]) / 255. - lowest_value) / total_number_of_steps
    new_value = lowest_value + step * increment
    return colorsys.hsv_to_rgb(float(hsv_color[0]), float(hsv_color[1]), new_value * 255.)


def default_colors(category_name: str) -> tuple[int, int, int]:
    """The devkit's RGB colour of a category: vehicles yellow, objects violet, humans and animals orange.

    Raises:
        ValueError: a category of none of these (the devkit's message).
    """
    if 'vehicle' in category_name:
        return 255, 255, 0
    elif 'object' in category_name:
        return 204, 0, 204
    elif 'human' in category_name or 'animal' in category_name:
        return 255, 153, 51
    else:
        raise ValueError(f"Cannot map {category_name} to a color.")


def draw_agent_boxes(center_agent_annotation: dict[str, Any], center_agent_pixels: tuple[float, float],
                     agent_history: History, base_image: np.ndarray, get_color: Callable[[str], tuple[int, int, int]],
                     resolution: float = 0.1) -> None:
    """Fill every record's box of `agent_history` into `base_image` (in place), the centre agent red, the others
    `get_color(category_name)`, each faded by its step when its agent has more than one."""
    agent_x, agent_y = center_agent_annotation['translation'][:2]
    records = [annotation for track in agent_history.values() for annotation in track]
    boxes = np.intp(track_boxes(records, (agent_x, agent_y), center_agent_pixels, resolution))
    b = 0
    for instance_token, track in agent_history.items():
        num_points = len(track)
        for i, annotation in enumerate(track):
            if instance_token == center_agent_annotation['instance_token']:
                color = (255, 0, 0)
            else:
                color = get_color(annotation['category_name'])
            if num_points > 1:  # no fading without history
                color = fade_color(color, i, num_points - 1)
            cv2.fillPoly(base_image, pts=[boxes[b]], color=color)
            b += 1


class AgentBoxesWithFadedHistory(AgentRepresentation):
    """The agents of a sample over `seconds_of_history` as faded boxes on black, in the window around one agent
    (`meters_ahead` up, `meters_behind`, `meters_left`, `meters_right`; `resolution` m per pixel)."""

    def __init__(self, helper, seconds_of_history: float = 2, frequency_in_hz: float = 2, resolution: float = 0.1,
                 meters_ahead: float = 40, meters_behind: float = 10, meters_left: float = 25,
                 meters_right: float = 25, color_mapping: Callable[[str], tuple[int, int, int]] | None = None):
        self.helper = helper
        self.seconds_of_history = seconds_of_history
        self.frequency_in_hz = frequency_in_hz
        if not resolution > 0:
            raise ValueError(f"Resolution must be positive. Received {resolution}.")
        self.resolution = resolution
        self.meters_ahead = meters_ahead
        self.meters_behind = meters_behind
        self.meters_left = meters_left
        self.meters_right = meters_right
        self.color_mapping = color_mapping or default_colors

    def make_representation(self, instance_token: str, sample_token: str) -> np.ndarray:
        """(rows, columns, 3) uint8 image of the agents around the instance at the sample."""
        # the whole square around the agent first, so that every actor is in the image before it is turned
        buffer = max([self.meters_ahead, self.meters_behind, self.meters_left, self.meters_right]) * 2
        image_side_length = int(buffer / self.resolution)
        central_track_pixels = (image_side_length / 2, image_side_length / 2)
        base_image = np.zeros((image_side_length, image_side_length, 3))
        history = self.helper.get_past_for_sample(sample_token, self.seconds_of_history, in_agent_frame=False,
                                                  just_xy=False)
        history = reverse_history(history)
        present_time = self.helper.get_annotations_for_sample(sample_token)
        history = add_present_time_to_history(present_time, history)
        center_agent_annotation = self.helper.get_sample_annotation(instance_token, sample_token)
        draw_agent_boxes(center_agent_annotation, central_track_pixels, history, base_image,
                         resolution=self.resolution, get_color=self.color_mapping)
        center_agent_yaw = quaternion_yaw(Quaternion(center_agent_annotation['rotation']))
        row_crop, col_crop = get_crops(self.meters_ahead, self.meters_behind, self.meters_left, self.meters_right,
                                       self.resolution, image_side_length)
        return rotate_and_crop(base_image, center_agent_yaw, row_crop, col_crop)
