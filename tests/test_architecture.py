"""The shape of the package, as docs/ARCHITECTURE.md describes it: every module listed there and nothing else, no
import circle (function-level imports included), the import rules, modules of ~300 lines or a reason, and a
command line and a front door that start light."""

from __future__ import annotations

import ast
import re
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
PACKAGE = REPO / "nuparquet"
MAX_LINES = 320  # "~300": a module past this says why in its docstring


def _modules() -> dict[str, Path]:
    out = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        name = ".".join(path.relative_to(REPO).with_suffix("").parts)
        out[name.removesuffix(".__init__")] = path
    return out


def _imports(path: Path, package: str, modules: dict[str, Path]) -> set[str]:
    """The nuparquet modules `path` imports anywhere (functions too), except under `if TYPE_CHECKING:`."""
    tree = ast.parse(path.read_text())
    skip = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            skip |= {id(n) for child in node.body for n in ast.walk(child)}
    found = set()
    for node in ast.walk(tree):
        if id(node) in skip or not isinstance(node, (ast.Import, ast.ImportFrom)):
            continue
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        else:
            base = node.module or ""
            if node.level:
                parts = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(parts + ([base] if base else []))
            names = [f"{base}.{a.name}" for a in node.names if f"{base}.{a.name}" in modules]
            if len(names) < len(node.names):
                names.append(base)
        for name in names:
            while name and name not in modules:
                name = name.rpartition(".")[0]
            if name.startswith("nuparquet"):
                found.add(name)
    return found


def _graph() -> dict[str, set[str]]:
    modules = _modules()
    graph = {}
    for name, path in modules.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        graph[name] = _imports(path, package, modules) - {name}
    return graph


def test_architecture_md_lists_every_module_and_no_other():
    listed = set(re.findall(r"^- `([\w/]+\.py)` — ", (REPO / "docs" / "ARCHITECTURE.md").read_text(), re.M))
    actual = {str(p.relative_to(PACKAGE)) for p in PACKAGE.rglob("*.py")}
    assert sorted(actual - listed) == [], "modules missing from docs/ARCHITECTURE.md"
    assert sorted(listed - actual) == [], "docs/ARCHITECTURE.md lists modules that do not exist"


def test_no_import_circle_inside_the_package():
    graph = _graph()
    index, low, stack, on_stack, circles = {}, {}, [], set(), []

    def visit(v):  # Tarjan's strongly connected components
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                circles.append(sorted(component))

    sys.setrecursionlimit(max(sys.getrecursionlimit(), 10_000))
    for v in graph:
        if v not in index:
            visit(v)
    assert circles == []


def test_the_import_rules_hold():
    graph = _graph()
    for name, imported in graph.items():
        if name.startswith("nuparquet.geometry"):  # numpy only
            assert all(i.startswith("nuparquet.geometry") for i in imported), (name, imported)
        if name.startswith("nuparquet.rendering"):  # never the JSON reader, never the converter
            assert not {i for i in imported if i.startswith(("nuparquet.conversion", "nuparquet.sources.tables",
                                                             "nuparquet.sources.json_records"))}, name
        if not name.startswith("nuparquet.cli"):  # the library never imports the command line
            assert not {i for i in imported if i.startswith("nuparquet.cli")}, name
        if not name.startswith(("nuparquet.synth", "nuparquet.cli")) and name != "nuparquet":
            assert not {i for i in imported if i.startswith("nuparquet.synth")}, name  # the generator is input


ROOT = {"errors", "options", "progress", "problems", "format", "version", "columns", "schemas", "splits", "channels",
        "atomic", "rle"}


def _layer(module: str) -> str:
    """The row of the import table a module belongs to: its package, or "root" for a root module."""
    parts = module.split(".")
    if len(parts) == 1:
        return "nuparquet"
    return "root" if parts[1] in ROOT else parts[1]


def _allowed_imports() -> dict[str, set[str]]:
    """docs/ARCHITECTURE.md's table: package -> the packages it may import besides the root ("*": any)."""
    text = (REPO / "docs" / "ARCHITECTURE.md").read_text()
    table = text[text.index("| package | may import"):].split("\n\n")[0]
    rows = [line.strip("|").split("|") for line in table.splitlines()[2:]]
    return {name.strip(): {p.strip() for p in allowed.split(",") if p.strip()} for name, allowed in rows}


def test_every_import_follows_an_arrow_of_the_architecture_table():
    """Every import between packages (functions included) is an arrow of docs/ARCHITECTURE.md's table, and the
    table names every package of the tree (a new package gets its row, so its arrows are a decision)."""
    allowed = _allowed_imports()
    packages = {p.name for p in PACKAGE.iterdir() if p.is_dir() and (p / "__init__.py").exists()}
    assert sorted(packages - set(allowed)) == [], "packages without a row in docs/ARCHITECTURE.md's import table"
    wrong = []
    for name, imported in _graph().items():
        layer = _layer(name)
        rule = allowed[layer]
        for target in imported:
            other = _layer(target)
            if other == layer or other == "root" or "*" in rule:
                continue
            if other not in rule:
                wrong.append(f"{name} -> {target}")
    assert wrong == [], "imports no arrow of docs/ARCHITECTURE.md allows"


def test_the_rendering_rooms_import_only_the_drawing_they_share():
    """rendering/video/ (the scene video) and rendering/pictures/ (one picture of one thing) import neither the
    other, and the drawing both use (rendering/*.py) imports neither room."""
    rooms = ("nuparquet.rendering.video", "nuparquet.rendering.pictures")

    def room(module: str) -> str | None:
        return next((r for r in rooms if module == r or module.startswith(r + ".")), None)

    wrong = []
    graph = _graph()
    for name, imported in graph.items():
        if not name.startswith("nuparquet.rendering"):
            continue
        for target in imported:
            if target.startswith("nuparquet.rendering") and room(target) is not None and room(target) != room(name):
                wrong.append(f"{name} -> {target}")
    assert wrong == [], "imports across the rendering rooms"
    assert any(room(m) == rooms[0] for m in graph) and any(room(m) == rooms[1] for m in graph)


def test_outputs_are_renamed_into_place_only_by_the_atomic_module():
    """One convention for atomic outputs (nuparquet/atomic.py): no other module renames files itself, so none
    invents its own partial names that the stale-partial sweep would not know."""
    offenders = []
    for path in PACKAGE.rglob("*.py"):
        if path.name == "atomic.py" and path.parent == PACKAGE:
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and \
                    node.func.attr in ("replace", "rename") and ast.unparse(node.func.value) == "os":
                offenders.append(f"{path.relative_to(REPO)}:{node.lineno}")
    assert offenders == []


def test_geometry_imports_numpy_and_nothing_else_but_numba_in_its_compiled_kernels():
    for path in sorted((PACKAGE / "geometry").glob("*.py")):
        tree = ast.parse(path.read_text())
        top_level = {id(node) for node in tree.body}
        for node in ast.walk(tree):
            if not isinstance(node, (ast.Import, ast.ImportFrom)) or getattr(node, "level", 0):
                continue
            roots = {a.name.split(".")[0] for a in node.names} if isinstance(node, ast.Import) \
                else {(node.module or "").split(".")[0]}
            third_party = roots - {"numpy", "nuparquet", "__future__"} - set(sys.stdlib_module_names)
            if path.name == "compiled.py":  # numba, and only where a kernel is built: never at import
                assert third_party <= {"numba"} and not (third_party and id(node) in top_level), (path.name, roots)
            else:
                assert not third_party, (path.name, roots)


def test_no_module_passes_300_lines_without_saying_why():
    long = []
    for path in PACKAGE.rglob("*.py"):
        text = path.read_text()
        if text.count("\n") > MAX_LINES and "~300-line" not in (ast.get_docstring(ast.parse(text)) or ""):
            long.append(str(path.relative_to(REPO)))
    assert long == []


def _loaded_after(code: str) -> set[str]:
    out = subprocess.run([sys.executable, "-c", f"{code}\nimport sys\nprint(' '.join(sorted(sys.modules)))"],
                         capture_output=True, text=True, check=True, cwd=REPO)
    return set(out.stdout.split())


@pytest.mark.parametrize("code", [
    "import nuparquet",
    "from nuparquet.cli.main import build_parser\nbuild_parser()",
])
def test_the_front_door_and_the_cli_parser_load_no_heavy_library(code):
    loaded = _loaded_after(code)
    assert not loaded & {"polars", "numpy", "pyarrow", "cv2", "duckdb", "numba", "av", "shapely", "matplotlib"}


def test_a_scene_render_loads_neither_pandas_nor_pyarrow(synth_out, tmp_path):
    """A render's fixed cost is part of its frames/s (BENCHMARKS row 5): pyarrow's imports take ~50 ms, its builders
    from Python values import pandas (~0.35 s) and a cast pyarrow.compute (~0.1 s), against ~0.25 s of drawing and
    encoding for 40 frames. The frame index written beside every video was the one place that used pyarrow."""
    loaded = _loaded_after(
        "from nuparquet.cli.main import main\n"
        f"assert main(['render', {str(synth_out)!r}, '--scene', 'scene-0001', '--channel', 'CAM_FRONT', '--scale', "
        f"'0.1', '--out', {str(tmp_path / 'v.mp4')!r}, '--frames-dir', {str(tmp_path / 'f')!r}, '--quiet']) == 0")
    assert (tmp_path / "v.frames.parquet").is_file() and (tmp_path / "f" / "frames.parquet").is_file()
    assert "cv2" in loaded and "av" in loaded  # it did render
    assert not loaded & {"pandas", "pyarrow", "pyarrow.compute"}


def test_the_front_door_lists_the_face_and_every_name_resolves():
    import nuparquet

    assert nuparquet.__all__ == [
        "open", "Dataset", "convert", "validate", "export_json", "synthesize", "render", "render_scenes",
        "build_index", "evaluate", "export_mcap", "export_mcap_scenes", "report", "export_coco", "CocoOptions",
        "ConvertOptions", "EngineOptions",
        "EvalOptions", "IndexOptions", "McapOptions", "RenderOptions", "ReportOptions", "SceneSelection", "SynthOptions",
        "NuparquetError", "UsageError", "InputError", "FormatError", "QueryError",
        "EnvironmentFault", "ProblemsFound", "UnitsFailed"]
    import nuparquet.conversion.options  # noqa: F401 - packages imported first must not shadow the verbs
    import nuparquet.rendering.video.options  # noqa: F401
    from nuparquet.conversion import convert
    from nuparquet.dataset import Dataset
    from nuparquet.errors import NuparquetError
    from nuparquet.rendering.video.pipeline import render

    assert nuparquet.convert is convert and nuparquet.render is render and nuparquet.Dataset is Dataset
    for name in nuparquet.__all__:
        value = getattr(nuparquet, name)
        assert callable(value), name
        if name.endswith(("Error", "Fault", "Found", "Failed")):
            assert issubclass(value, NuparquetError), name
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        nuparquet.nope  # noqa: B018


def test_every_cli_command_has_its_verb_in_the_front_door():
    """One verb per command, same names: the CLI's modules and the library's face name the same things."""
    import nuparquet
    from nuparquet.cli.main import COMMANDS

    verb = {"synth": "synthesize", "index": "build_index", "eval": "evaluate", "info": "open", "stats": "open",
            "sql": "open"}
    for command in COMMANDS:
        assert verb.get(command, command) in nuparquet.__all__, command


def test_no_two_test_modules_share_a_file_name():
    """The test folders are not packages: pytest imports each test module by its file name, and test modules import
    helpers from one another by name (`from test_reference import assert_same`), so a second `test_x.py` in
    another folder makes one of them import the other (or fail to collect) when both run in one process."""
    names: dict[str, list[str]] = {}
    for path in sorted((REPO / "tests").rglob("*.py")):
        names.setdefault(path.name, []).append(str(path.relative_to(REPO)))
    shared = {name: paths for name, paths in names.items() if len(paths) > 1 and name not in ("__init__.py", "conftest.py")}
    assert shared == {}
