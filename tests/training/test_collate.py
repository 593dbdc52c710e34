"""`collate` on hand-written items (shapes and values by construction) and on real `Samples` items."""

from __future__ import annotations

import numpy as np
import pytest

from nuparquet.training.collate import collate


def _item(n_points: int, n_boxes: int, seed: int) -> dict:
    rng = np.random.default_rng(seed)
    return {"sample_token": f"s{seed}", "timestamp_us": 1000 + seed, "lidar_sweeps": seed,
            "points": rng.normal(size=(n_points, 5)).astype(np.float32),
            "gt_bboxes_3d": rng.normal(size=(n_boxes, 9)).astype(np.float32),
            "gt_labels_3d": np.arange(n_boxes), "num_lidar_pts": np.arange(n_boxes),
            "img": rng.integers(0, 255, (2, 4, 6, 3), dtype=np.uint8), "lidar2img": rng.normal(size=(2, 4, 4))}


def test_points_are_concatenated_with_lengths_and_the_rest_stacked_or_listed():
    items = [_item(5, 2, 0), _item(0, 0, 1), _item(3, 1, 2)]
    batch = collate(items)
    assert batch["points_lengths"].tolist() == [5, 0, 3]
    np.testing.assert_array_equal(batch["points"], np.concatenate([i["points"] for i in items]))
    assert batch["img"].shape == (3, 2, 4, 6, 3) and batch["img"].dtype == np.uint8
    np.testing.assert_array_equal(batch["lidar2img"][2], items[2]["lidar2img"])
    assert [len(b) for b in batch["gt_bboxes_3d"]] == [2, 0, 1]
    np.testing.assert_array_equal(batch["gt_bboxes_3d"][0], items[0]["gt_bboxes_3d"])
    assert batch["timestamp_us"].tolist() == [1000, 1001, 1002] and batch["sample_token"] == ["s0", "s1", "s2"]
    assert batch["lidar_sweeps"].tolist() == [0, 1, 2]


def test_padded_points_hold_each_item_then_zeros():
    items = [_item(5, 1, 0), _item(2, 1, 1)]
    batch = collate(items, pad_points=True)
    assert batch["points"].shape == (2, 5, 5) and batch["points_lengths"].tolist() == [5, 2]
    np.testing.assert_array_equal(batch["points"][1, :2], items[1]["points"])
    assert not batch["points"][1, 2:].any()


def test_images_of_different_sizes_stay_a_list():
    a, b = _item(1, 0, 0), _item(1, 0, 1)
    b["img"] = np.zeros((2, 8, 6, 3), np.uint8)
    assert isinstance(collate([a, b])["img"], list)
    with pytest.raises(ValueError):
        collate([])


def test_a_batch_of_real_samples(synth_out):
    from nuparquet.training.samples import Samples

    samples = Samples(synth_out, "train", sweeps=1, version="v1.0-trainval")
    items = [samples[i] for i in (1, 2)]
    batch = collate(items)
    assert batch["points"].shape == (sum(len(i["points"]) for i in items), 5)
    assert batch["img"].shape[:2] == (2, len(samples.cameras))
    assert batch["lidar2img"].shape == (2, len(samples.cameras), 4, 4)


def test_the_package_names_the_verbs():
    import nuparquet.training as training
    from nuparquet.training import shards

    assert training.collate is collate and callable(training.collate)
    assert training.SampleStream is shards.SampleStream and training.worker_init_fn is shards.worker_init_fn
    assert training.Samples.__name__ == "Samples"


def test_radar_points_queue_and_the_new_fields():
    rng = np.random.default_rng(3)

    def frame(n_radar: int, seed: int, exists: bool) -> dict:
        return {"sample_token": f"s{seed}", "radar_points": rng.normal(size=(n_radar, 19)).astype(np.float32),
                "can_bus": rng.normal(size=18), "gt_masks_bev": rng.integers(0, 2, (6, 4, 4), dtype=np.uint8),
                "prev_bev_exists": exists, "cam2lidar": rng.normal(size=(2, 4, 4))}

    items = []
    for b, (n, exists) in enumerate(((4, True), (0, False), (2, True))):
        item = frame(n, b, exists)
        item["queue"] = [frame(3 - k, 10 * b + k, k > 0) for k in range(2)]
        item["queue_index"] = np.array([b, b + 1, b + 2])
        items.append(item)
    batch = collate(items)
    assert batch["radar_points_lengths"].tolist() == [4, 0, 2] and batch["radar_points"].shape == (6, 19)
    np.testing.assert_array_equal(batch["radar_points"][4:], items[2]["radar_points"])
    assert batch["can_bus"].shape == (3, 18) and batch["gt_masks_bev"].shape == (3, 6, 4, 4)
    np.testing.assert_array_equal(batch["cam2lidar"][1], items[1]["cam2lidar"])
    assert batch["prev_bev_exists"].dtype == bool and batch["prev_bev_exists"].tolist() == [True, False, True]
    assert batch["queue_index"].tolist() == [[0, 1, 2], [1, 2, 3], [2, 3, 4]]
    assert len(batch["queue"]) == 2  # position by position, oldest first
    first = batch["queue"][0]
    assert first["sample_token"] == ["s0", "s10", "s20"] and first["radar_points_lengths"].tolist() == [3, 3, 3]
    assert batch["queue"][1]["prev_bev_exists"].tolist() == [True, True, True]
    padded = collate(items, pad_points=True)
    assert padded["radar_points"].shape == (3, 4, 19) and not padded["radar_points"][1].any()
    assert padded["queue"][1]["radar_points"].shape == (3, 2, 19)


def test_a_batch_of_real_samples_with_radar_can_bus_and_a_queue(synth_out):
    from nuparquet.training.samples import Samples

    samples = Samples(synth_out, "train", lidar=False, cameras=(), radars="all", can_bus=True, queue_length=2,
                      version="v1.0-trainval")
    items = [samples[i] for i in (5, 6)]  # the first scene's last sample, the second's first
    batch = collate(items)
    assert batch["radar_points"].shape == (sum(len(i["radar_points"]) for i in items), 19)
    assert batch["can_bus"].shape == (2, 18) and batch["prev_bev_exists"].tolist() == [True, False]
    assert batch["queue"][0]["sample_token"] == [items[0]["queue"][0]["sample_token"],
                                                 items[1]["queue"][0]["sample_token"]]
