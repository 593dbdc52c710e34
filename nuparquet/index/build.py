"""`build_index`: the training index of a converted directory (see the package docstring)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from nuparquet.dataset import Dataset, as_dataset
from nuparquet.errors import UsageError
from nuparquet.index import bevformer, legacy, lidarseg, parquet, records, splits
from nuparquet.index.cam_instances import camera_instances
from nuparquet.index.compute import compute
from nuparquet.index.inputs import read_inputs
from nuparquet.index.options import IndexOptions
from nuparquet.index.v2_arrays import v2_arrays
from nuparquet.index.write import write_infos_pickle, write_parquet_dir, write_pickle
from nuparquet.options import resolve
from nuparquet.progress import OnProgress, Reporter

__all__ = ["IndexOptions", "build_index"]


CHUNK_SAMPLES = 1000  # entries built and pickled at a time: bounds memory at trainval scale


def _entries(arrays, *, corrected: bool = False):
    """The v2 entries of `arrays`, CHUNK_SAMPLES at a time."""
    for lo in range(0, len(arrays.token), CHUNK_SAMPLES):
        yield records.v2_infos(arrays.slice(lo, min(lo + CHUNK_SAMPLES, len(arrays.token))), corrected=corrected,
                               first_index=lo)


def build_index(dataset: str | Path | Dataset, out, options: IndexOptions | None = None, *,
                on_progress: OnProgress | None = None, **fields) -> dict:
    """Write the info pickle(s) of `options` (or keyword fields of `IndexOptions`: `format="bevformer"`, ...) of
    `dataset` (a `Dataset` or a path) into the folder `out`; returns {split: pickle path} (plus "infos": the Parquet
    directory when written, "<split>_mono3d": the COCO file of mmdet3d-legacy). Raises InputError when the Parquet
    lacks what is needed."""
    options = resolve(IndexOptions, options, fields)
    ds = as_dataset(dataset)
    is_legacy = options.format == "mmdet3d-legacy"
    v2 = options.format == "mmdet3d" and options.info_version == 2
    version = splits.converter_version(ds.version, options.version)
    test = version == "v1.0-test"
    wanted = splits.split_names(version) if options.split == "all" else (options.split,)
    if options.split != "all" and options.split not in splits.split_names(version):
        raise UsageError(f"{version} has no {options.split} split (it has {', '.join(splits.split_names(version))})")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)

    steps = 3 + len(wanted) * (2 if (options.parquet and v2) or is_legacy else 1)
    with Reporter(on_progress, "index", total=steps) as progress:
        inputs = read_inputs(ds, options.cameras, options.lidar)
        can_bus = None
        sample_links = None
        if options.format == "bevformer":
            can_bus = bevformer.can_bus_vectors(ds, inputs.sample_token)
            sample = ds.scan("tables/sample").select("prev", "next").collect()
            sample_links = (sample["prev"].to_numpy(), sample["next"].to_numpy())
        progress.advance(step="read tables")
        computed = compute(inputs, options.cameras, options.lidar, options.max_sweeps,
                           with_annotations=not test, with_cam_instances=v2)
        # the lidarseg lookup is v1.4.0's (BEVFormer's and 0.17's converters never make it)
        mask_files = None if test or options.format != "mmdet3d" else lidarseg.semantic_mask_files(
            ds, inputs.data.token[computed.lidar_row], inputs.sample_token)
        if is_legacy:  # get_2d_boxes reads sample['anns'] whatever the version: a test version has none
            legacy_records = camera_instances(inputs, options.cameras, legacy=True)
            width, height = (a.reshape(computed.cam_row.shape) for a in
                             legacy.camera_image_sizes(ds, inputs.data.token[computed.cam_row.ravel()]))
        progress.advance(step="compute")
        assigned = splits.assign_splits(version, inputs.scene_token, inputs.scene_name, inputs.sample_scene)
        progress.advance(step="splits")
        written: dict = {}
        tables = {}
        for split in wanted:
            samples = np.flatnonzero(assigned == split)
            # BEVFormer, UniAD and VAD name their files nuscenes_infos_temporal_<split>.pkl
            temporal = "temporal_" if options.format == "bevformer" else ""
            target = out / f"nuscenes_infos_{temporal}{split}.pkl"
            if is_legacy:
                infos = records.v1_infos(computed, samples, options.cameras, options.data_prefix, test)
                write_pickle(target, {"infos": legacy.legacy_infos(infos), "metadata": {"version": version}})
                written[split] = target
                progress.advance(step=f"write {split}")
                coco = out / f"nuscenes_infos_{split}_mono3d.coco.json"
                legacy.write_mono3d_coco(coco, computed, legacy_records, samples, options.data_prefix, width, height)
                written[f"{split}_mono3d"] = coco
            elif options.info_version == 1:
                infos = records.v1_infos(computed, samples, options.cameras, options.data_prefix, test,
                                         mask_files)
                if options.format == "bevformer":
                    infos = bevformer.bevformer_infos(computed, infos, samples, *sample_links, can_bus)
                write_pickle(target, {"infos": infos, "metadata": {"version": version}})
            else:
                arrays = v2_arrays(computed, samples, options.cameras, options.data_prefix,
                                   mask_files=mask_files)
                last_ignored, all_ignored = records.v2_ignored(arrays)
                write_infos_pickle(target, {"metainfo": records.v2_metainfo(version, last_ignored)}, "data_list",
                                   _entries(arrays))
                if options.corrected:
                    fixed = v2_arrays(computed, samples, options.cameras, options.data_prefix, corrected=True,
                                      mask_files=mask_files)
                    write_infos_pickle(out / f"nuscenes_infos_{split}_corrected.pkl",
                                       {"metainfo": records.v2_metainfo(version, all_ignored)}, "data_list",
                                       _entries(fixed, corrected=True))
                if options.parquet:
                    table = parquet.infos_table(arrays, split)
                    if table is not None:
                        tables[split] = table
                    progress.advance(step=f"parquet {split}")
            written[split] = target
            progress.advance(step=f"write {split}")
        if tables:
            write_parquet_dir(out / "infos", tables)
            written["infos"] = out / "infos"
    return written
