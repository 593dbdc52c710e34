"""Deterministic synthetic datasets in the exact nuScenes layout (`nuparquet synth`).

`synthesize(out_dir, scenes=N)` writes a dataroot that the nuscenes-devkit and nuparquet both read:

    out_dir/<version>/{attribute,calibrated_sensor,...,visibility}.json   the 13 tables
    out_dir/maps/<map token>.png                                         tiny placeholder semantic maps
    out_dir/maps/expansion/<location>.json                               map expansion v1.3 along the roads
    out_dir/samples/<CHANNEL>/..., out_dir/sweeps/<CHANNEL>/...          with images and/or lidar

It is a producer of nuScenes JSON like any real dataset: nothing else in nuparquet depends on its internals.
Same arguments -> byte-identical tables (tokens come from a seeded generator, never from the clock).

Modules: `taxonomy` (names and calibration style), `plan` (logs, scene start times, rigs), `timeline`
(sample and sensor timestamps), `road` (centreline and speed profiles), `world` (ego motion, objects,
annotations), `tables` (JSON), `sensors` (JPEG / lidar / radar files), `rigid` (quaternions and boxes),
`tokens`; `options` (`SynthOptions`), `generate` (`synthesize`).
"""

from __future__ import annotations

__all__ = ["SynthOptions", "synthesize"]


def __getattr__(name: str):
    # Loaded on first use: the CLI builds `synth --help` from the options without loading OpenCV and the generator.
    if name == "synthesize":
        from nuparquet.synth.generate import synthesize

        return synthesize
    if name == "SynthOptions":
        from nuparquet.synth.options import SynthOptions

        return SynthOptions
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
