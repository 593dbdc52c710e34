"""The streamed info pickle (entries pickled chunk by chunk, memo cleared between chunks) loads equal to
pickle.dump of the whole dict: same keys in order, same values and numpy scalar types."""

from __future__ import annotations

import pickle

import numpy as np

from nuparquet.index.write import write_infos_pickle


def test_streamed_pickle_loads_like_the_whole_dict(tmp_path):
    shared = "CAM_FRONT"  # the same string object in every entry: memoized within a chunk only
    entries = [{"sample_idx": i, "token": f"t{i}", "cam": shared, "bbox": [np.float64(i / 3), np.float64("nan")],
                "n": np.int64(i), "valid": np.bool_(i % 2), "m": [[float(i), -0.0], [1e300, 5e-324]]}
               for i in range(7)]
    head = {"metainfo": {"categories": {"car": 0, "debris": -1}, "version": "v1.0-mini"}}
    chunks = [entries[:3], [], entries[3:4], entries[4:]]  # several, an empty one, a single entry (APPEND)
    write_infos_pickle(tmp_path / "x.pkl", head, "data_list", iter(chunks))
    loaded = pickle.loads((tmp_path / "x.pkl").read_bytes())
    expected = pickle.loads(pickle.dumps(head | {"data_list": entries}))
    assert list(loaded) == ["metainfo", "data_list"]
    assert repr(loaded) == repr(expected)  # repr: NaN compares unequal, its repr does not
    types = [[type(v) for v in e["bbox"]] + [type(e["n"]), type(e["valid"])] for e in loaded["data_list"]]
    assert types == [[np.float64, np.float64, np.int64, np.bool_]] * 7
    assert [e["m"][0][1] for e in loaded["data_list"]] == [-0.0] * 7
    assert str(loaded["data_list"][0]["m"][0][1]) == "-0.0"


def test_no_entries(tmp_path):
    write_infos_pickle(tmp_path / "x.pkl", {"metainfo": {}}, "data_list", iter([]))
    assert pickle.loads((tmp_path / "x.pkl").read_bytes()) == {"metainfo": {}, "data_list": []}
