"""`nuparquet info` names the dataset's sensor channels (the names `render --channel` and `--lidar` use)."""

from __future__ import annotations

import json

from conftest import LYFT_RIG_VERSION
from nuparquet.cli.main import main


def test_info_lists_the_cameras_in_layout_rows_and_the_lidars_with_the_reference(lyft_rig_root, lyft_rig_out, capsys):
    assert main(["info", str(lyft_rig_out), "--format", "json"]) == 0
    channels = json.loads(capsys.readouterr().out)["channels"]
    sensors = json.loads((lyft_rig_root / LYFT_RIG_VERSION / "sensor.json").read_text())
    assert sorted(c for row in channels["camera_layout"] for c in row) == sorted(
        s["channel"] for s in sensors if s["modality"] == "camera")
    assert channels["lidars"] == sorted(s["channel"] for s in sensors if s["modality"] == "lidar")
    assert channels["reference_lidar"] == "LIDAR_TOP" and channels["radars"] == []
    assert main(["info", str(lyft_rig_out)]) == 0
    text = capsys.readouterr().out
    assert "CAM_FRONT_ZOOMED" in text and "(reference: LIDAR_TOP)" in text and "radars:    (none)" in text


def test_info_lists_the_scene_names_render_and_stats_take(synth_root, synth_out, capsys):
    from conftest import SYNTH_VERSION

    names = [s["name"] for s in json.loads((synth_root / SYNTH_VERSION / "scene.json").read_text())]
    assert main(["info", str(synth_out)]) == 0
    line = next(l for l in capsys.readouterr().out.splitlines() if l.strip().startswith("scenes:"))
    assert line.split()[1:] == sorted(names)


def test_info_prints_when_the_manifest_says_the_output_was_created(synth_out, capsys):
    import datetime as dt

    created = json.loads((synth_out / "manifest.json").read_text())["created_utc"]
    assert dt.datetime.fromisoformat(created.replace("Z", "+00:00")).tzinfo is not None  # a UTC time, present
    assert main(["info", str(synth_out), "--format", "json"]) == 0
    assert json.loads(capsys.readouterr().out)["created_utc"] == created
    assert main(["info", str(synth_out)]) == 0
    assert f" at {created}\n" in capsys.readouterr().out
