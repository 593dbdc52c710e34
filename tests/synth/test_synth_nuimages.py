"""`synth --format nuimages`: deterministic, and its masks are those pycocotools encodes for its polygons."""

from __future__ import annotations

import base64
import filecmp

import numpy as np
from pycocotools import mask as cocomask

from nuparquet.synth import synthesize
from nuparquet.synth.coco_rle import encode


def test_the_same_arguments_write_the_same_bytes(tmp_path):
    a = synthesize(tmp_path / "a", scenes=1, samples_per_scene=2, seed=3, family="nuimages", version="v1.0-mini")
    b = synthesize(tmp_path / "b", scenes=1, samples_per_scene=2, seed=3, family="nuimages", version="v1.0-mini")
    files = sorted(p.relative_to(a) for p in a.rglob("*") if p.is_file())
    assert len(files) == 10 + 2 * 13  # the tables, 13 images per sample
    assert files == sorted(p.relative_to(b) for p in b.rglob("*") if p.is_file())
    assert all(filecmp.cmp(a / f, b / f, shallow=False) for f in files)
    c = synthesize(tmp_path / "c", scenes=1, samples_per_scene=2, seed=4, family="nuimages", version="v1.0-mini")
    assert not filecmp.cmp(a / "v1.0-mini" / "object_ann.json", c / "v1.0-mini" / "object_ann.json", shallow=False)


def test_the_generator_s_encoder_is_pycocotools_s():
    rng = np.random.default_rng(5)
    for i in range(200):
        mask = (rng.random(tuple(int(v) for v in rng.integers(1, 30, 2))) < rng.random()).astype(np.uint8)
        if i % 7 == 0:
            mask[:] = i % 2
        ours = encode(mask)
        assert base64.b64decode(ours["counts"]) == cocomask.encode(np.asfortranarray(mask))["counts"]
        assert ours["size"] == list(mask.shape)
