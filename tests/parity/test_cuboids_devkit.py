"""geometry.Cuboids against the devkit's Box: corners, a move into another frame, take and concat."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest
from nuscenes.utils.data_classes import Box
from pyquaternion import Quaternion

from nuparquet.geometry import CuboidRows, Cuboids


def random_cuboids(rng: np.random.Generator, n: int, at="global") -> Cuboids:
    q = rng.normal(size=(n, 4))
    return Cuboids.of(rng.uniform(-500, 500, (n, 3)), rng.uniform(0.5, 8, (n, 3)),
                      q / np.linalg.norm(q, axis=1, keepdims=True), at)


def test_corners_and_a_move_equal_the_devkits_box_rotate_then_translate():
    rng = np.random.default_rng(7)
    cuboids = random_cuboids(rng, 50)
    q = rng.normal(size=4)
    rotation, translation = q / np.linalg.norm(q), rng.uniform(-10, 10, 3)
    moved = cuboids.moved(translation, rotation, at="ego")
    assert moved.at == "ego" and len(moved) == 50
    for i in range(len(cuboids)):
        box = Box(cuboids.translation_m[i], cuboids.size_wlh_m[i], Quaternion(cuboids.rotation_wxyz[i]))
        np.testing.assert_allclose(cuboids.corners()[i], box.corners().T, rtol=0, atol=1e-9)
        box.rotate(Quaternion(rotation))
        box.translate(translation)
        np.testing.assert_allclose(moved.translation_m[i], box.center, rtol=0, atol=1e-9)
        np.testing.assert_allclose(moved.corners()[i], box.corners().T, rtol=0, atol=1e-9)
        np.testing.assert_allclose(moved.rotation_wxyz[i], box.orientation.elements, rtol=0, atol=1e-12)


def test_per_box_poses_move_each_box_by_its_own_pose():
    rng = np.random.default_rng(8)
    cuboids = random_cuboids(rng, 5)
    q = rng.normal(size=(5, 4))
    rotations, translations = q / np.linalg.norm(q, axis=1, keepdims=True), rng.uniform(-10, 10, (5, 3))
    moved = cuboids.moved(translations, rotations, at="sensor")
    for i in range(5):
        one = cuboids.take([i]).moved(translations[i], rotations[i], at="sensor")
        np.testing.assert_allclose(moved.translation_m[i], one.translation_m[0], rtol=0, atol=1e-12)
        np.testing.assert_allclose(moved.rotation_wxyz[i], one.rotation_wxyz[0], rtol=0, atol=1e-15)


def test_take_concat_and_the_frame_name():
    rng = np.random.default_rng(9)
    a, b = random_cuboids(rng, 3), random_cuboids(rng, 2)
    both = Cuboids.concat([a, b])
    assert len(both) == 5
    np.testing.assert_array_equal(both.take([4, 0]).translation_m, np.stack([b.translation_m[1], a.translation_m[0]]))
    assert len(Cuboids.concat([], at="ego")) == 0 and Cuboids.concat([], at="ego").at == "ego"
    with pytest.raises(ValueError, match="different frames"):
        Cuboids.concat([a, random_cuboids(rng, 1, at="ego")])
    with pytest.raises(ValueError, match="at must be one of"):
        Cuboids.empty("lidar")
    with pytest.raises(ValueError, match="different lengths"):
        Cuboids(np.zeros((2, 3)), np.zeros((1, 3)), np.zeros((2, 4)))


def test_rows_beside_cuboids_are_taken_with_them():
    @dataclass(frozen=True)
    class Scored(CuboidRows):
        score: np.ndarray
        label: str = "x"

    rng = np.random.default_rng(10)
    rows = Scored(random_cuboids(rng, 4), np.array([0.1, 0.9, 0.5, 0.7]))
    kept = rows.take(rows.score > 0.6)
    assert len(kept) == 2 and kept.label == "x"
    np.testing.assert_array_equal(kept.score, [0.9, 0.7])
    np.testing.assert_array_equal(kept.translation_m, rows.translation_m[[1, 3]])
