"""`nuparquet sql` reads the dataset only: file-reading table functions are refused unless the caller opts in."""

from __future__ import annotations

import pytest

import nuparquet
from nuparquet.cli.main import main
from nuparquet.errors import QueryError


@pytest.mark.parametrize("query", ["SELECT * FROM read_csv('/etc/hostname')", "select * from READ_PARQUET ('x.parquet')",
                                   "SELECT count(*) FROM scenes, read_json('/etc/passwd')"])
def test_file_reading_functions_are_refused(synth_out, capsys, query):
    assert main(["sql", str(synth_out), query]) == 1
    assert "reads only this dataset" in capsys.readouterr().err
    with pytest.raises(QueryError, match="allow_file_access"):
        nuparquet.open(synth_out).sql(query)


def test_the_words_inside_strings_are_not_calls(synth_out):
    result = nuparquet.open(synth_out).sql("SELECT 'read_csv(x)' AS a, count(*) AS n FROM scenes")
    assert result["a"].to_list() == ["read_csv(x)"]


def test_opting_in_allows_them(synth_out, tmp_path):
    path = tmp_path / "mine.csv"
    path.write_text("x\n1\n2\n")
    ds = nuparquet.open(synth_out)
    assert ds.sql(f"SELECT sum(x) AS s FROM read_csv('{path}')", allow_file_access=True)["s"].to_list() == [3]
