"""nuImages against `nuimages.NuImages` (nuscenes-devkit 1.2.0, test-only) on generated nuImages data: masks,
`get_segmentation`, the list counts, `render_image`'s pixels and the COCO export decoded by pycocotools."""

from __future__ import annotations

import json
import types
from collections import Counter
from contextlib import redirect_stdout
from io import StringIO

import numpy as np
import pytest
from nuimages import NuImages
from nuimages.utils.utils import mask_decode, name_to_index_mapping

from nuparquet.conversion import convert
from nuparquet.dataset import open_dataset
from nuparquet.errors import UsageError
from nuparquet.export.coco import coco_instances, export_coco
from nuparquet.nuimages.counts import attribute_counts, category_counts
from nuparquet.nuimages.segmentation import category_indices, segmentation
from nuparquet.rendering.pictures.nuimages import render_nuimage
from nuparquet.synth import synthesize

VERSION = "v1.0-mini"


@pytest.fixture(scope="module")
def nuim(tmp_path_factory):
    root = synthesize(tmp_path_factory.mktemp("nuimages") / "root", scenes=2, samples_per_scene=3, seed=4,
                      family="nuimages", version=VERSION)
    out = tmp_path_factory.mktemp("nuimages-out") / "out"
    convert(root, VERSION, out)
    return NuImages(VERSION, str(root), verbose=False), open_dataset(out)


def test_every_mask_decodes_to_the_devkit_s_pixels(nuim):
    devkit, ds = nuim
    for table in ("object_ann", "surface_ann"):
        records = [r for r in getattr(devkit, table) if r["mask"] is not None]
        ours = ds.masks([r["token"] for r in records])
        assert ours.shape[0] == len(records) > 0
        for record, mask in zip(records, ours):
            expected = mask_decode(record["mask"])
            assert mask.dtype == expected.dtype and np.array_equal(mask, expected), record["token"]
            assert 0 < expected.sum() < expected.size  # neither empty nor full: the runs' order matters


def test_masks_of_tokens_that_are_not_there_are_refused_naming_the_first_and_counting_the_rest(nuim):
    _, ds = nuim
    with pytest.raises(UsageError) as caught:
        ds.masks(["nope-1", "nope-2", "nope-3"])
    assert str(caught.value) == "no object_ann or surface_ann 'nope-1' (and 2 more)"
    with pytest.raises(UsageError) as caught:
        ds.masks("nope-1")
    assert str(caught.value) == "no object_ann or surface_ann 'nope-1'"


def test_a_mask_that_runs_over_the_image_s_edges_decodes_exactly(nuim):
    devkit, ds = nuim
    edge = [r for r in devkit.object_ann if r["mask"] is not None and r["bbox"][0] == 0 and r["bbox"][1] == 0]
    assert edge  # the generator's first image has one; column-major runs that wrap at the border
    assert np.array_equal(ds.masks(edge[0]["token"]), mask_decode(edge[0]["mask"]))


def test_an_annotation_without_a_mask_gives_zeros_and_a_null_area(nuim):
    devkit, ds = nuim
    missing = [r for r in devkit.object_ann if r["mask"] is None]
    assert missing
    assert not ds.masks(missing[0]["token"]).any()
    row = ds.scan("objects").filter(token=missing[0]["token"]).collect()
    assert row["mask_area"].to_list() == [None] and row["mask_counts"].to_list() == [None]


def test_mask_areas_are_pycocotools_areas(nuim):
    from pycocotools import mask as cocomask

    devkit, ds = nuim
    areas = dict(ds.scan("objects").select("token", "mask_area").collect().iter_rows())
    for record in devkit.object_ann:
        if record["mask"] is not None:
            assert areas[record["token"]] == int(mask_decode(record["mask"]).sum())
    first = next(r for r in devkit.surface_ann if r["mask"] is not None)
    rle = dict(first["mask"], counts=__import__("base64").b64decode(first["mask"]["counts"]))
    assert ds.scan("surfaces").filter(token=first["token"]).collect()["mask_area"][0] == cocomask.area(rle)


def test_get_segmentation_equals_the_devkit_s(nuim):
    devkit, ds = nuim
    seen = set()
    for sample in devkit.sample:
        semantic, instance = segmentation(ds, sample["key_camera_token"])
        expected_semantic, expected_instance = devkit.get_segmentation(sample["key_camera_token"])
        assert semantic.dtype == expected_semantic.dtype and instance.dtype == expected_instance.dtype
        assert np.array_equal(semantic, expected_semantic) and np.array_equal(instance, expected_instance)
        seen |= set(np.unique(semantic).tolist()) | {("instances", int(instance.max()))}
    assert {24, 31, ("instances", 6)} <= seen  # the driveable surface, the ego, an image of six objects


def test_class_indices_are_the_devkit_s_mapping(nuim):
    devkit, _ = nuim
    names = [c["name"] for c in devkit.category]
    assert category_indices(names) == name_to_index_mapping(devkit.category)


def test_segmentation_of_a_non_keyframe_is_refused(nuim):
    devkit, ds = nuim
    sweep = next(sd for sd in devkit.sample_data if not sd["is_key_frame"])
    with pytest.raises(UsageError, match="not a keyframe"):
        segmentation(ds, sweep["token"])


def _devkit_counts(devkit, method) -> list[tuple[int, ...]]:
    """The numbers of each line the devkit's printer prints (its names are cut to 24 characters)."""
    text = StringIO()
    with redirect_stdout(text):
        method()
    lines = [line for line in text.getvalue().splitlines()[2:] if line.strip()]
    return [tuple(int(v) for v in line.split()[:2] if v.isdigit()) for line in lines]


def test_list_categories_counts_equal_ours(nuim):
    devkit, ds = nuim
    ours = category_counts(ds)
    objects = Counter(r["category_token"] for r in devkit.object_ann)
    surfaces = Counter(r["category_token"] for r in devkit.surface_ann)
    names = {c["token"]: c["name"] for c in devkit.category}
    expected = {names[t]: (objects[t], surfaces[t]) for t in names if objects[t] or surfaces[t]}
    assert dict(zip(ours["name"], zip(ours["object_anns"], ours["surface_anns"]))) == expected
    printed = sorted(_devkit_counts(devkit, devkit.list_categories))
    assert printed == sorted(zip(ours["object_anns"], ours["surface_anns"]))
    sample = devkit.sample[1]["token"]
    one = category_counts(ds, [sample])
    assert sorted(_devkit_counts(devkit, lambda: devkit.list_categories(sample_tokens=[sample]))) == \
        sorted(zip(one["object_anns"], one["surface_anns"]))


def test_list_attributes_counts_equal_ours(nuim):
    devkit, ds = nuim
    ours = attribute_counts(ds)
    assert sorted((n,) for n in ours["annotations"]) == sorted(_devkit_counts(devkit, devkit.list_attributes))
    assert ours["annotations"].sum() == sum(len(r["attribute_tokens"]) for r in devkit.object_ann)
    assert 2 in Counter(len(r["attribute_tokens"]) for r in devkit.object_ann)  # an emergency vehicle's two


def _devkit_picture(devkit, sd_token, **kwargs) -> np.ndarray:
    """The RGBA picture `render_image` hands to matplotlib, before matplotlib scales and composites it."""
    import nuimages.nuimages as module

    seen = {}
    fake = types.SimpleNamespace(figure=lambda *a, **k: None, axis=lambda *a, **k: None,
                                 imshow=lambda im, *a, **k: seen.setdefault("im", np.asarray(im)),
                                 savefig=lambda *a, **k: None, close=lambda *a, **k: None)
    real, module.plt = module.plt, fake
    try:
        devkit.render_image(sd_token, **kwargs)
    finally:
        module.plt = real
    return seen["im"]


@pytest.mark.parametrize("kwargs", [{}, {"box_line_width": 3}, {"annotation_type": "surfaces"},
                                    {"annotation_type": "objects"}])
def test_render_image_draws_the_devkit_s_mask_and_box_pixels(nuim, kwargs):
    """Pixel for pixel where both decode the JPEG alike (libjpeg); within 1 elsewhere (Pillow's and OpenCV's
    decoders may round an image differently)."""
    devkit, ds = nuim
    from PIL import Image

    drawn = []
    for sample in devkit.sample:
        sd = devkit.get("sample_data", sample["key_camera_token"])
        expected = _devkit_picture(devkit, sd["token"], **kwargs)[:, :, :3]
        ours = render_nuimage(ds, sd["token"], **kwargs)
        base = np.asarray(Image.open(f"{devkit.dataroot}/{sd['filename']}").convert("RGB"))
        assert ours.shape == expected.shape
        if np.array_equal(render_nuimage(ds, sd["token"], annotation_type="none"), base):
            assert np.array_equal(ours, expected), sd["token"]
        else:
            assert np.abs(ours.astype(int) - expected.astype(int)).max() <= 1
        drawn.append((ours != base).any())
    assert sum(drawn) >= len(drawn) - 1  # something was drawn (the first image's surface has no mask)


def test_render_image_draws_only_the_tokens_asked_for(nuim):
    devkit, ds = nuim
    sd = devkit.sample[0]["key_camera_token"]
    chosen = [r["token"] for r in devkit.object_ann if r["sample_data_token"] == sd and r["mask"] is not None][:1]
    expected = _devkit_picture(devkit, sd, annotation_type="objects", object_tokens=chosen)[:, :, :3]
    ours = render_nuimage(ds, sd, annotation_type="objects", object_tokens=chosen)
    assert np.abs(ours.astype(int) - expected.astype(int)).max() <= 1
    other = next(r["token"] for r in devkit.object_ann if r["sample_data_token"] != sd)
    with pytest.raises(UsageError, match="not an annotation of this image"):
        render_nuimage(ds, sd, object_tokens=[other])
    # attributes are written after the category name: the devkit asserts it, we refuse saying so
    with pytest.raises(AssertionError, match="with_category must be True"):
        devkit.render_image(sd, with_category=False, with_attributes=True)
    with pytest.raises(UsageError, match="^with_attributes needs with_category$"):
        render_nuimage(ds, sd, with_category=False, with_attributes=True)


def test_coco_export_loads_in_pycocotools_and_decodes_to_the_devkit_s_masks(nuim, tmp_path):
    from pycocotools.coco import COCO

    devkit, ds = nuim
    path = export_coco(ds, tmp_path / "coco.json", classes="all")
    coco = COCO(str(path))
    keyframes = [sd for sd in devkit.sample_data if sd["is_key_frame"]]
    assert [coco.imgs[i]["token"] for i in sorted(coco.imgs)] == [sd["token"] for sd in keyframes]
    by_image = {img["id"]: img["token"] for img in coco.imgs.values()}
    masked = {r["token"]: r for r in devkit.object_ann if r["mask"] is not None}
    assert len(coco.anns) == len(masked)
    names = {c["token"]: c["name"] for c in devkit.category}
    indices = name_to_index_mapping(devkit.category)
    for ann in coco.anns.values():
        record = next(r for r in masked.values() if r["sample_data_token"] == by_image[ann["image_id"]]
                      and r["bbox"][0] == ann["bbox"][0] and r["bbox"][1] == ann["bbox"][1]
                      and np.array_equal(mask_decode(r["mask"]), coco.annToMask(ann)))
        x0, y0, x1, y1 = record["bbox"]
        assert ann["bbox"] == [x0, y0, x1 - x0, y1 - y0] and ann["iscrowd"] == 0
        assert ann["area"] == int(mask_decode(record["mask"]).sum())
        assert coco.cats[ann["category_id"]]["name"] == names[record["category_token"]]
        assert ann["category_id"] == indices[names[record["category_token"]]]


def _mmdet3d_file(devkit) -> str:
    """mmdetection3d's tools/dataset_converters/nuimage_converter.py `export_nuim_to_coco`, restated line for line
    without its semantic-mask PNGs (the JSON it dumps with `json.dump`)."""
    import base64

    classes = ("car", "truck", "trailer", "bus", "construction_vehicle", "bicycle", "motorcycle", "pedestrian",
               "traffic_cone", "barrier")
    mapping = {"movable_object.barrier": "barrier", "vehicle.bicycle": "bicycle", "vehicle.bus.bendy": "bus",
               "vehicle.bus.rigid": "bus", "vehicle.car": "car", "vehicle.construction": "construction_vehicle",
               "vehicle.motorcycle": "motorcycle", "human.pedestrian.adult": "pedestrian",
               "human.pedestrian.child": "pedestrian", "human.pedestrian.construction_worker": "pedestrian",
               "human.pedestrian.police_officer": "pedestrian", "movable_object.trafficcone": "traffic_cone",
               "vehicle.trailer": "trailer", "vehicle.truck": "truck"}
    categories = [dict(id=classes.index(n), name=n) for n in classes]
    cat2id = {c["name"]: c["id"] for c in categories}
    images = []
    for info in devkit.sample_data:
        if info["is_key_frame"]:
            images.append(dict(id=len(images), token=info["token"], file_name=info["filename"], width=info["width"],
                               height=info["height"]))
    annotations = []
    for img in images:
        anns = sorted([o for o in devkit.object_ann if o["sample_data_token"] == img["token"]], key=lambda k: k["token"])
        for ann in anns:
            name = devkit.get("category", ann["category_token"])["name"]
            if ann["mask"] is None or name not in mapping:
                continue
            x_min, y_min, x_max, y_max = ann["bbox"]
            mask = {"counts": base64.b64decode(ann["mask"]["counts"]).decode(), "size": ann["mask"]["size"]}
            anno = dict(image_id=img["id"], category_id=cat2id[mapping[name]],
                        bbox=[x_min, y_min, x_max - x_min, y_max - y_min], area=(x_max - x_min) * (y_max - y_min),
                        segmentation=mask, iscrowd=0)
            anno.update(id=len(annotations))
            annotations.append(anno)
    return json.dumps(dict(images=images, annotations=annotations, categories=categories))


def test_the_default_coco_file_is_mmdetection3d_s_byte_for_byte(nuim, tmp_path):
    devkit, ds = nuim
    path = export_coco(ds, tmp_path / "mmdet.json")
    assert path.read_text() == _mmdet3d_file(devkit)
    assert any(a["category_id"] == 0 for a in coco_instances(ds)["annotations"])  # vehicle.car -> car, id 0
