"""The benchmark datasets, built once and cached under .bench-cache/ (gitignored), or under the folder named by
the environment variable NUPARQUET_BENCH_CACHE (one set shared by several worktrees: every benchmark script
reads its data through `CACHE`).

    .venv/bin/python benchmarks/bench_data.py            # build whatever is missing, print the paths
    NUPARQUET_BENCH_CACHE=/data/bench .venv/bin/python benchmarks/run_all.py

- `trainval/`: `nuparquet synth .bench-cache/trainval --scenes 850 --samples-per-scene 40 --version
  v1.0-trainval --no-can-bus` — nuScenes trainval scale, metadata only (~1.17M annotations, ~2.6M sample_data and
  ego_pose; ~2.6 GB of JSON, about half a minute to write).
- `trainval-out/`: its conversion (`nuparquet convert`), read by the query, projection and analytics
  benchmarks. The convert benchmark writes its own outputs elsewhere and never touches this one.
- `render/`: 2 scenes x 40 samples with 1600x900 camera JPEGs (keyframes and sweeps), and `render-out/`.
- `extract-out/`: the conversion of the real two-scene nuScenes extract in ../shared/data (keyframe photos),
  when it is there: the render benchmark also runs on real images.

Each cache directory holds `.bench-params.json` (the arguments that built it; for a conversion also a digest
of schemas/); a directory whose parameters differ, or that is incomplete, is rebuilt. Delete .bench-cache/ to
start over.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from harness import NUPARQUET, REPO, log  # noqa: E402

CACHE = Path(os.environ.get("NUPARQUET_BENCH_CACHE") or REPO / ".bench-cache").resolve()
TRAINVAL_VERSION = "v1.0-trainval"
TRAINVAL_SCENES = 850
SAMPLES_PER_SCENE = 40
RENDER_VERSION = "v1.0-synth"
RENDER_SCENES = 2
PARAMS = ".bench-params.json"

TRAINVAL_ROOT = CACHE / "trainval"
TRAINVAL_OUT = CACHE / "trainval-out"
RENDER_ROOT = CACHE / "render"
RENDER_OUT = CACHE / "render-out"
EXTRACT_ROOT = REPO.parent / "shared" / "data" / "nuscenes-extract"  # real nuScenes photos (optional)
EXTRACT_VERSION = "v1.0-mini-extract"
EXTRACT_OUT = CACHE / "extract-out"


def synth_command(root: Path, scenes: int, version: str, *, with_images: bool = False,
                  samples_per_scene: int = SAMPLES_PER_SCENE, can_bus: bool = True) -> list[str]:
    return [*NUPARQUET, "synth", str(root), "--scenes", str(scenes), "--samples-per-scene", str(samples_per_scene),
            "--version", version, "--quiet", *(["--with-images"] if with_images else []),
            *([] if can_bus else ["--no-can-bus"])]


def convert_command(root: Path, version: str, out: Path) -> list[str]:
    return [*NUPARQUET, "convert", str(root), "--version", version, "--out", str(out), "--overwrite", "--quiet"]


def _schemas_digest() -> str:
    """A digest of schemas/ (the single definition of every column): a conversion is redone when it changes."""
    digest = hashlib.sha256()
    for path in sorted((REPO / "schemas").rglob("*.json")):
        digest.update(path.relative_to(REPO).as_posix().encode() + b"\0" + path.read_bytes())
    return digest.hexdigest()[:16]


def _params_match(directory: Path, params: dict) -> bool:
    try:
        return json.loads((directory / PARAMS).read_text()) == params
    except (OSError, json.JSONDecodeError):
        return False


def _synth(root: Path, scenes: int, version: str, *, with_images: bool,
           samples_per_scene: int = SAMPLES_PER_SCENE, can_bus: bool = True) -> Path:
    params = {"synth": {"scenes": scenes, "samples_per_scene": samples_per_scene, "version": version,
                        "with_images": with_images, "seed": 0, **({} if can_bus else {"can_bus": False})}}
    if (root / version / "sample_data.json").is_file() and _params_match(root, params):
        return root
    if root.exists():
        shutil.rmtree(root)
    log(f"building {root} ({scenes} scenes x {samples_per_scene} samples{', images' if with_images else ''}) ...")
    subprocess.run(synth_command(root, scenes, version, with_images=with_images, samples_per_scene=samples_per_scene,
                                 can_bus=can_bus), check=True, cwd=REPO)
    (root / PARAMS).write_text(json.dumps(params) + "\n")
    return root


def _convert(root: Path, version: str, out: Path) -> Path:
    source = json.loads((root / PARAMS).read_text()) if (root / PARAMS).is_file() else None
    params = {"convert": {"dataroot": str(root.resolve()), "version": version, "source": source,
                          "schemas": _schemas_digest()}}
    if (out / "manifest.json").is_file() and _params_match(out, params):
        return out
    log(f"converting {root} -> {out} ...")
    subprocess.run(convert_command(root, version, out), check=True, cwd=REPO)
    (out / PARAMS).write_text(json.dumps(params) + "\n")
    return out


def trainval_root() -> Path:
    """The trainval-scale synthetic dataroot (JSON only). Without the CAN bus expansion: row 1 compares with
    DuckDB copying the 13 metadata tables, and row 8 measures the CAN bus on its own data."""
    return _synth(TRAINVAL_ROOT, TRAINVAL_SCENES, TRAINVAL_VERSION, with_images=False, can_bus=False)


def trainval_out() -> Path:
    """The conversion of `trainval_root()`."""
    return _convert(trainval_root(), TRAINVAL_VERSION, TRAINVAL_OUT)


def scenes_root(scenes: int) -> Path:
    """A smaller metadata-only set with trainval's shape (`scenes` x 40 samples), for quicker runs of rows 1
    and 4 (`--scenes N`); `scenes=850` is `trainval_root()`."""
    if scenes == TRAINVAL_SCENES:
        return trainval_root()
    return _synth(CACHE / f"scenes-{scenes}", scenes, TRAINVAL_VERSION, with_images=False, can_bus=False)


def scenes_out(scenes: int) -> Path:
    if scenes == TRAINVAL_SCENES:
        return trainval_out()
    return _convert(scenes_root(scenes), TRAINVAL_VERSION, CACHE / f"scenes-{scenes}-out")


SCALE_OUT_SCENES = 10
SCALE_OUT_SAMPLES = 20


def scale_out_root() -> Path:
    """10 scenes x 20 samples with 1600x900 camera JPEGs: the many-scene render of the scale-out rows."""
    return _synth(CACHE / "scale-out", SCALE_OUT_SCENES, RENDER_VERSION, with_images=True,
                  samples_per_scene=SCALE_OUT_SAMPLES)


def scale_out_out() -> Path:
    return _convert(scale_out_root(), RENDER_VERSION, CACHE / "scale-out-out")


def render_root() -> Path:
    """2 scenes x 40 samples with 1600x900 camera JPEGs."""
    return _synth(RENDER_ROOT, RENDER_SCENES, RENDER_VERSION, with_images=True)


def render_out() -> Path:
    return _convert(render_root(), RENDER_VERSION, RENDER_OUT)


def extract_out() -> Path | None:
    """The conversion of the real two-scene nuScenes extract (keyframe photos only), if ../shared has it."""
    if not (EXTRACT_ROOT / EXTRACT_VERSION).is_dir():
        return None
    return _convert(EXTRACT_ROOT, EXTRACT_VERSION, EXTRACT_OUT)


def main() -> None:
    for name, build in (("trainval", trainval_root), ("trainval-out", trainval_out), ("render", render_root),
                        ("render-out", render_out), ("extract-out", extract_out)):
        print(f"{name}: {build()}")


if __name__ == "__main__":
    main()
