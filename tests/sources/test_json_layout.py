"""The whitespace of JSON array files (`sources.json_layout`): detected from the first record and the last bytes, and
written back so that export-json returns nuScenes' tables (indent 2 or 0), the generator's (indent 0), compact
arrays and its own output byte for byte; any other layout is written one record a line."""

from __future__ import annotations

import io
import json
import math

import pytest

from conftest import EXTRACT_VERSION
from nuparquet.export.json_files import export_json
from nuparquet.sources import json_layout

RECORDS = [{"token": "a", "translation": [1.5, -0.0, 1e-07], "camera_intrinsic": [], "nested": {"k": [[1, 2], []]},
            "text": "line\nbreak \u00e9", "nan": math.nan},
           {"token": "b", "translation": [0.1, 2, 3.0], "camera_intrinsic": [[1.0, 0.0], [0.0, 1.0]], "nested": {},
            "text": "", "nan": 1}]


def written(records, layout) -> str:
    out = io.StringIO()
    json_layout.write_array(out, records, layout)
    return out.getvalue()


@pytest.mark.parametrize("indent", [None, 0, 1, 2, 4])
@pytest.mark.parametrize("newline", [False, True])
@pytest.mark.parametrize("records", [RECORDS, RECORDS[:1], []])
def test_python_json_layouts_are_detected_and_written_back_byte_for_byte(tmp_path, indent, newline, records):
    text = json.dumps(records, indent=indent) + ("\n" if newline else "")
    path = tmp_path / "t.json"
    path.write_text(text)
    layout = json_layout.detect(path)
    assert layout is not None and layout["newline"] is newline
    if records:  # every indent writes [] alike
        assert layout["indent"] == indent
    assert written(records, layout) == text


def test_export_json_own_layout_is_detected(tmp_path):
    text = written(RECORDS, None)
    assert text == "[\n" + ",\n".join(json.dumps(r) for r in RECORDS) + "\n]\n"  # one record a line, as before
    (tmp_path / "t.json").write_text(text)
    layout = json_layout.detect(tmp_path / "t.json")
    assert layout == {"indent": json_layout.LINES, "newline": True} and written(RECORDS, layout) == text


@pytest.mark.parametrize("text", [
    json.dumps(RECORDS, separators=(",", ":")),  # other separators
    json.dumps(RECORDS, indent=2).replace('"token": "a"', '"token":  "a"'),  # hand-edited first record
    json.dumps(RECORDS, indent="\t"),  # tabs
    json.dumps(RECORDS, indent=2) + "\n\n",  # two newlines at the end
    json.dumps(RECORDS, indent=2)[:-1] + " ]",  # a space before the closing bracket
    json.dumps(RECORDS, indent=2).replace("},\n  {", "},\n\n  {"),  # another separator between records
])
def test_other_layouts_are_not_claimed(tmp_path, text):
    (tmp_path / "t.json").write_text(text)
    assert json_layout.detect(tmp_path / "t.json") is None


def test_a_first_record_longer_than_the_head_is_not_claimed(tmp_path, monkeypatch):
    monkeypatch.setattr(json_layout, "HEAD_BYTES", 40)
    (tmp_path / "t.json").write_text(json.dumps(RECORDS, indent=2))
    assert json_layout.detect(tmp_path / "t.json") is None


def test_the_real_extract_tables_come_back_byte_for_byte(extract_root, extract_out, tmp_path):
    export_json(extract_out, tmp_path / "back")
    originals = sorted((extract_root / EXTRACT_VERSION).glob("*.json"))
    assert len(originals) == 13
    for path in originals:
        assert (tmp_path / "back" / EXTRACT_VERSION / path.name).read_bytes() == path.read_bytes(), path.name


def test_the_generator_tables_come_back_byte_for_byte(synth_root, synth_out, tmp_path):
    export_json(synth_out, tmp_path / "back")
    version = synth_out.joinpath("manifest.json")
    version = json.loads(version.read_text())["source"]["version"]
    for path in sorted((synth_root / version).glob("*.json")):
        assert (tmp_path / "back" / version / path.name).read_bytes() == path.read_bytes(), path.name


def test_a_file_whose_last_bytes_begin_inside_a_utf8_character_is_detected(tmp_path):
    """Text written unescaped (`ensure_ascii=False`, as tools outside Python's defaults write names and descriptions)
    can put the start of the last 16 bytes, which `detect` reads for the closing bracket, inside a multi-byte
    character: the layout is still that of the first record and the closing bracket, not a UnicodeDecodeError."""
    records = [{"token": "a", "description": "plain"},
               {"token": "b", "description": "Stra\u00dfe \u00e9\u00e9\u00e9\u00e9\u00e9!"}]
    text = json.dumps(records, indent=2, ensure_ascii=False) + "\n"
    data = text.encode("utf-8")
    assert data[-16] & 0xC0 == 0x80  # the 16th byte from the end continues a character
    (tmp_path / "t.json").write_bytes(data)
    assert json_layout.detect(tmp_path / "t.json") == {"indent": 2, "newline": True}
