"""`build_index`: the training index of a converted directory (see the package docstring)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from nuparquet.dataset import Dataset, as_dataset
from nuparquet.errors import UsageError
from nuparquet.index import bevformer, parquet, records, splits
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


def build_index(path: str | Path | Dataset, options: IndexOptions | None = None, *,
                on_progress: OnProgress | None = None, **fields) -> dict:
    """Write the info pickle(s) of `options` (or keyword fields of `IndexOptions`: `out="infos"`, ...) into
    `options.out`; returns {split: pickle path} (plus "infos": the Parquet directory when written). Raises
    InputError when the Parquet lacks what is needed."""
    options = resolve(IndexOptions, options, fields)
    ds = as_dataset(path)
    version = splits.converter_version(ds.version, options.version)
    test = version == "v1.0-test"
    wanted = splits.split_names(version) if options.split == "all" else (options.split,)
    if options.split != "all" and options.split not in splits.split_names(version):
        raise UsageError(f"{version} has no {options.split} split (it has {', '.join(splits.split_names(version))})")
    out = Path(options.out)
    out.mkdir(parents=True, exist_ok=True)

    steps = 3 + len(wanted) * (2 if options.parquet and options.info_version == 2 else 1)
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
                           with_annotations=not test, with_cam_instances=options.info_version == 2)
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
            if options.info_version == 1:
                infos = records.v1_infos(computed, samples, options.cameras, options.data_prefix, test)
                if options.format == "bevformer":
                    infos = bevformer.bevformer_infos(computed, infos, samples, *sample_links, can_bus)
                write_pickle(target, {"infos": infos, "metadata": {"version": version}})
            else:
                arrays = v2_arrays(computed, samples, options.cameras, options.data_prefix)
                last_ignored, all_ignored = records.v2_ignored(arrays)
                write_infos_pickle(target, {"metainfo": records.v2_metainfo(version, last_ignored)}, "data_list",
                                   _entries(arrays))
                if options.corrected:
                    fixed = v2_arrays(computed, samples, options.cameras, options.data_prefix, corrected=True)
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
