"""How input problems read (nuparquet.problems): where (file, record index, token), the message, "warning: " only
for warnings, control characters from the data escaped, long values cut with their length; expectations by hand."""

from __future__ import annotations

from nuparquet.problems import Problem, ProblemsFound, echo, format_problems


def test_echo_quotes_escapes_control_characters_and_cuts_long_values_with_their_length():
    assert echo("CAM_FRONT") == "'CAM_FRONT'"
    assert echo("CAM_FRONT", quote=False) == "CAM_FRONT"
    # an escape sequence in the data must not reach the terminal raw, quoted or not
    assert echo("a\x1b[2Jb\x9bc\u2028d", quote=False) == "a\\x1b[2Jb\\x9bc\\u2028d"
    assert echo("a\x1b[2Jb") == "'a\\x1b[2Jb'"
    assert echo(["x", "\x07"]) == "['x', '\\x07']"
    assert echo("x" * 150) == "'" + "x" * 99 + "... (150 characters)"  # the length of the value, not of its repr
    assert echo("é" * 2000, limit=10, quote=False) == "é" * 10 + "... (2,000 characters)"
    assert echo(12345678, limit=3) == "123... (8 characters)"
    assert echo("x" * 98) == "'" + "x" * 98 + "'"  # 100 characters with the quotes: not cut


def test_a_problem_reads_file_index_token_and_message_with_warning_only_for_warnings():
    assert str(Problem("sample_data.json", "timestamp is not an integer", 3, "abc")) == (
        "sample_data.json[3] token=abc: timestamp is not an integer")
    assert str(Problem("sample_data.json", "missing", 0)) == "sample_data.json[0]: missing"
    assert str(Problem("ego_pose.json", "missing", token="t")) == "ego_pose.json token=t: missing"
    assert str(Problem("calibrated_sensor.json", "rotation is not a unit quaternion", 1, warning=True)) == (
        "warning: calibrated_sensor.json[1]: rotation is not a unit quaternion")
    assert str(Problem("scene.json", "name\x1b[31m is odd", token="to\x00k")) == (
        "scene.json token=to\\x00k: name\\x1b[31m is odd")


def test_format_problems_lists_the_first_ones_then_counts_the_rest_and_the_summaries():
    problems = [Problem("a.json", f"bad {i}", i) for i in range(4)]
    problems.append(Problem("b.json", "and 7 more records without a token", omitted=7))
    assert format_problems(problems, limit=2).splitlines() == [
        "a.json[0]: bad 0", "a.json[1]: bad 1", "... and 2 more problems not shown",
        "b.json: ... and 7 more records without a token"]
    error = ProblemsFound(problems)
    assert str(error).splitlines()[0] == "11 problems in the input:" and error.problems == problems
    assert str(ProblemsFound(problems[:1])) == "1 problem in the input:\na.json[0]: bad 0"
