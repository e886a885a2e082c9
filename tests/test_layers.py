"""The layers of docs/development.md, imports flowing one way: core <- io <- pipeline <- cli.

The cli imports the pipeline, the pipeline io (and core), io imports core, and nothing imports
a layer above its own. The import graph is read from the package's source (its AST, imports
inside functions too); what a command or a module loads is checked in a fresh interpreter each
time, so what the test process has already imported does not hide a dependency.
"""

from __future__ import annotations

import ast
import functools
import re
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import ROOT, imported, write


@pytest.mark.slow
def test_core_imports_numpy_only() -> None:
    assert imported("import tumblecal_cli.core.model", ("pandas", "pyarrow", "typer", "click", "rich", "yaml")) == []


@pytest.mark.slow
@pytest.mark.parametrize("module", ["gate", "solvers", "blocks"])
def test_core_layer_imports_numpy_only(module: str) -> None:
    assert (
        imported(f"import tumblecal_cli.core.{module}", ("pandas", "pyarrow", "typer", "click", "rich", "yaml")) == []
    )


@pytest.mark.slow
@pytest.mark.parametrize(
    "body",
    [
        pytest.param("import tumblecal_cli.cli", id="import"),
        pytest.param(
            "from tumblecal_cli.cli import main\n"
            "import contextlib, io\n"
            "from tumblecal_cli.cli import app\n"
            "commands = [c.name or c.callback.__name__ for c in app.registered_commands if c.callback]\n"
            "assert {'solve', 'apply', 'batch', 'segment', 'verify', 'show', 'check'} <= set(commands)\n"
            "with contextlib.redirect_stdout(io.StringIO()):\n"
            "    assert main(['--help']) == 0\n"
            "    for name in commands:\n"
            "        assert main([name, '--help']) == 0, name\n"
            "    assert main(['solve', '--poses', 'a.csv', '-x=b.csv', '--help']) == 0\n"
            "    assert main(['--version']) == 0",
            id="help-and-version",
        ),
    ],
)
def test_cli_help_does_not_import_the_numeric_stack(body: str) -> None:
    assert imported(body, ("numpy", "pyarrow", "pandas", "yaml", "distributed", "dask")) == []


@pytest.mark.slow
def test_batch_module_is_light() -> None:
    """A batch worker imports what solving takes (numpy, pyarrow: imports at the top of the
    pipeline), never the command line's Typer and Rich, nor pandas; Dask only when asked."""
    assert (
        imported("import tumblecal_cli.pipeline.batch.units", ("pandas", "typer", "rich", "distributed", "dask")) == []
    )


def test_package_root_is_light() -> None:
    assert imported("import tumblecal_cli", ("numpy", "pyarrow", "pandas", "typer", "rich")) == []


@pytest.mark.slow
def test_a_solve_and_apply_run_without_pandas() -> None:
    """pandas is the Python API's DataFrame interface only: a whole solve and apply run without it."""
    body = (
        "import contextlib, io, tempfile, os\n"
        "from tumblecal_cli.cli import main\n"
        "d = tempfile.mkdtemp()\n"
        "cal = os.path.join(d, 'cal.json')\n"
        "poses = [os.path.join('sample_data', f) for f in ('x.csv', 'y.csv', 'z.csv')]\n"
        "with contextlib.redirect_stderr(io.StringIO()):\n"
        "    assert main(['solve', '--poses', *poses, '-o', cal]) == 0\n"
        "    assert main(['apply', '--cal', cal, 'sample_data/capture.csv', '-o', os.path.join(d, 'c.csv')]) == 0"
    )
    assert imported(body, ("pandas", "numpy", "pyarrow")) == ["numpy", "pyarrow"]


@pytest.mark.slow
def test_apply_loads_only_what_correcting_needs(tmp_path: Path) -> None:
    """A station's ``tumblecal apply -q`` pays for numpy, pyarrow and orjson, not for Rich, the
    solvers, the batch runner or Typer's build of every other command (README "Speed")."""
    cal = tmp_path / "cal.json"
    poses = [str(ROOT / "sample_data" / f"{a}.csv") for a in "xyz"]
    solve = [sys.executable, "-m", "tumblecal_cli", "solve", "-q", "--poses", *poses, "-o", str(cal)]
    subprocess.run(solve, check=True)
    body = (
        "import typer.main\n"
        "from tumblecal_cli.cli import main\n"
        "built = []\n"
        "build = typer.main.get_command\n"
        "typer.main.get_command = lambda group: built.append(len(group.registered_commands)) or build(group)\n"
        f"argv = ['apply', '-q', '--cal', {str(cal)!r}, 'sample_data/capture.csv', '-o', {str(tmp_path / 'c.csv')!r}]\n"
        "assert main(argv) == 0\n"
        "assert built == [1], built\n"
    )
    watch = (
        "rich",
        "tumblecal_cli.core.solvers",
        "tumblecal_cli.pipeline.batch.units",
        "tumblecal_cli.pipeline.solve.solving",
    )
    assert imported(body, watch) == []
    assert (tmp_path / "c.csv").read_bytes().count(b"\n") > 100


@pytest.mark.slow
def test_quiet_solve_and_noise_load_no_rich(tmp_path: Path) -> None:
    """``-q`` prints nothing for people: a station's ``solve -q`` (poses or a log) and ``noise -q``
    pay nothing for Rich (15 ms of start-up)."""
    poses = [str(ROOT / "sample_data" / f"{a}.csv") for a in "xyz"]
    faces = np.repeat(np.vstack([np.eye(3), -np.eye(3)]), 3000, axis=0)  # six faces, 3 s each at 1 kHz
    noisy = faces + np.random.default_rng(3).normal(0, 0.002, size=faces.shape)
    log = str(write(tmp_path / "log.csv", np.column_stack([np.arange(len(faces)) / 1000.0, noisy])))
    runs = [
        ["solve", "-q", "--poses", *poses, "-o", str(tmp_path / "a.json")],
        ["solve", "-q", "--log", log, "-o", str(tmp_path / "b.json")],
        ["noise", "-q", "--rate", "100", str(ROOT / "sample_data" / "x.csv")],
    ]
    for argv in runs:
        body = f"from tumblecal_cli.cli import main\nassert main({argv!r}) in (0, 1)\n"
        assert imported(body, ("rich",)) == [], argv


# -- the import graph and the size of a command (an AST reading of the package) --------------

PACKAGE = ROOT / "tumblecal_cli"


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


@functools.cache
def _trees() -> dict[Path, ast.Module]:
    """Each source file of the package, parsed once for the tests below."""
    return {path: ast.parse(path.read_text()) for path in PACKAGE.rglob("*.py")}


@functools.cache
def _imports() -> dict[str, set[str]]:
    """Each module of the package and the package's modules it imports (anywhere in it,
    inside functions and TYPE_CHECKING blocks too), resolved to modules that exist."""
    modules = {_module_name(p): p for p in _trees()}
    graph: dict[str, set[str]] = {}
    for name, path in modules.items():
        found: set[str] = set()
        for node in ast.walk(_trees()[path]):
            targets: list[str] = []
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                targets = [f"{node.module}.{a.name}" for a in node.names] + [node.module]
            for target in targets:
                while target and target not in modules:
                    target = target.rpartition(".")[0]
                if target.startswith("tumblecal_cli") and target != name:
                    found.add(target)
        graph[name] = found
    return graph


def _in(module: str, layer: str) -> bool:
    return module == f"tumblecal_cli.{layer}" or module.startswith(f"tumblecal_cli.{layer}.")


def test_nothing_outside_the_cli_imports_it() -> None:
    """(``python -m tumblecal_cli`` is the command line's entry point, as the console script is.)"""
    wrong = [(m, t) for m, ts in _imports().items() if not _in(m, "cli") for t in ts if _in(t, "cli")]
    assert wrong == [("tumblecal_cli.__main__", "tumblecal_cli.cli")]


def test_core_imports_nothing_of_io_pipeline_or_cli() -> None:
    graph = _imports()
    wrong = [
        (m, t) for m, ts in graph.items() if _in(m, "core") for t in ts if not (_in(t, "core") or t.endswith("errors"))
    ]
    assert wrong == []


def test_io_imports_neither_the_pipeline_nor_the_cli() -> None:
    graph = _imports()
    wrong = [(m, t) for m, ts in graph.items() if _in(m, "io") for t in ts if _in(t, "pipeline") or _in(t, "cli")]
    assert wrong == []


def test_no_import_cycle() -> None:
    """Among the package's modules (a package's __init__ that only gathers its own modules'
    names for the public API is left out: it imports them lazily, by name)."""
    graph = {m: {t for t in ts if t != "tumblecal_cli"} for m, ts in _imports().items() if m != "tumblecal_cli"}
    state: dict[str, int] = {}
    cycles: list[list[str]] = []

    def visit(node: str, path: list[str]) -> None:
        state[node] = 1
        for nxt in sorted(graph.get(node, set())):
            if state.get(nxt) == 1:
                cycles.append([*path[path.index(nxt) :], nxt] if nxt in path else [node, nxt])
            elif nxt not in state:
                visit(nxt, [*path, nxt])
        state[node] = 2

    for module in sorted(graph):
        if module not in state:
            visit(module, [module])
    # the cli package's __init__ imports its command modules so that they register; each of
    # them imports cli.app, never the package's __init__: that is no cycle
    assert [c for c in cycles if "tumblecal_cli.cli" not in c] == []


def test_a_command_body_fits_on_a_screen() -> None:
    """Each command function: parse, one pipeline call, render; at most 40 lines of body."""
    long: list[tuple[str, int]] = []
    for path in (PACKAGE / "cli").glob("*.py"):
        for node in _trees()[path].body:
            if (
                isinstance(node, ast.FunctionDef) and any("command" in ast.unparse(d) for d in node.decorator_list)
            ) or (isinstance(node, ast.FunctionDef) and node.name == "batch"):
                body = node.body[1:] if isinstance(node.body[0], ast.Expr) else node.body  # the docstring is help
                lines = (body[-1].end_lineno or 0) - body[0].lineno + 1
                if lines > 40:
                    long.append((f"{path.name}:{node.name}", lines))
    assert long == []


def _import_statements(node: ast.AST, inside: bool = False) -> Iterator[tuple[ast.Import | ast.ImportFrom, bool]]:
    """Each import statement under ``node``, and whether it is inside a function."""
    for child in ast.iter_child_nodes(node):
        if isinstance(child, ast.Import | ast.ImportFrom):
            yield child, inside
        yield from _import_statements(child, inside or isinstance(child, ast.FunctionDef))


def test_pandas_only_inside_the_pipeline_functions() -> None:
    """pandas is the DataFrame interface's: imported inside functions of the pipeline only."""
    wrong = []
    for path, tree in _trees().items():
        for node, inside in _import_statements(tree):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else [node.module or ""]
            if any(n.split(".")[0] == "pandas" for n in names) and ("pipeline" not in path.parts or not inside):
                wrong.append(f"{path.relative_to(ROOT)}:{node.lineno}")
    assert wrong == []


# -- the shape of the code: what a reader can rely on (docs/development.md) -----------------

LAYERS = ("core", "io", "pipeline")
#: Imported where they are used, never at a module's top: optional extras and the heavy
#: libraries only some calls need (pandas: the DataFrame interface; PyYAML: YAML files; orjson:
#: guarded, apply's fast writer; ctypes: glibc's malloc tuning; psycopg: records on a PostgreSQL server).
LAZY = ("pandas", "matplotlib", "dask", "distributed", "yaml", "orjson", "ctypes", "psycopg")


def _functions() -> list[tuple[Path, ast.FunctionDef | ast.AsyncFunctionDef]]:
    out = []
    for path in sorted(PACKAGE.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                out.append((path, node))
    return out


def _where(path: Path, node: ast.AST) -> str:
    return f"{path.relative_to(ROOT)}:{getattr(node, 'name', '')}"


def test_no_function_outside_the_cli_takes_more_than_8_parameters() -> None:
    wrong = []
    for path, fn in _functions():
        if "cli" in path.relative_to(PACKAGE).parts[:1]:
            continue
        a = fn.args
        names = [*a.posonlyargs, *a.args, *a.kwonlyargs]
        count = len(names) + (a.vararg is not None) + (a.kwarg is not None)
        count -= bool(names) and names[0].arg in ("self", "cls")
        if count > 8:
            wrong.append((_where(path, fn), count))
    assert wrong == []


def test_no_module_over_900_lines_and_no_function_body_over_80() -> None:
    big = [(str(p.relative_to(ROOT)), n) for p in PACKAGE.rglob("*.py") if (n := len(p.read_text().splitlines())) > 900]
    long = []
    for path, fn in _functions():
        body = fn.body[1:] if len(fn.body) > 1 and isinstance(fn.body[0], ast.Expr) else fn.body
        lines = (body[-1].end_lineno or 0) - body[0].lineno + 1
        if lines > 80:
            long.append((_where(path, fn), lines))
    assert (big, long) == ([], [])


def test_any_is_rare() -> None:
    """``Any`` only at a boundary (a JSON document, a third-party object), each with a reason."""
    count = sum(len(re.findall(r"\bAny\b", p.read_text())) for p in PACKAGE.rglob("*.py"))
    assert count <= 60


def test_imports_at_the_top_of_core_io_and_pipeline() -> None:
    """numpy and the package's own modules are imported at a module's top; only LAZY inside functions."""
    wrong = []
    for path, fn in _functions():
        if path.relative_to(PACKAGE).parts[0] not in LAYERS:
            continue
        for node in ast.walk(fn):
            if isinstance(node, ast.Import | ast.ImportFrom):
                names = [a.name for a in node.names] if isinstance(node, ast.Import) else [node.module or ""]
                if not all(n.split(".")[0] in LAZY for n in names):
                    wrong.append(f"{_where(path, fn)}: {ast.unparse(node)}")
    assert wrong == []


def test_module_names_are_unique_across_core_io_and_pipeline() -> None:
    seen: dict[str, list[str]] = {}
    for layer in LAYERS:
        for path in (PACKAGE / layer).rglob("*.py"):
            if path.stem != "__init__":
                seen.setdefault(path.stem, []).append(str(path.parent.relative_to(PACKAGE)))
    assert {name: layers for name, layers in seen.items() if len(layers) > 1} == {}


def test_each_package_docstring_names_every_module_in_it() -> None:
    """Each package of the layers (and its rooms) lists its modules and rooms in its docstring,
    ``name`` for a module and ``name/`` for a room, and lists nothing that is not there."""
    wrong = []
    for init in sorted(PACKAGE.rglob("__init__.py")):
        if init.parent == PACKAGE:
            continue
        doc = ast.get_docstring(_trees()[init]) or ""
        have = {p.stem for p in init.parent.glob("*.py") if p.stem != "__init__"}
        have |= {f"{p.name}/" for p in init.parent.iterdir() if (p / "__init__.py").is_file()}
        named = set(re.findall(r"``([a-z_]+/?)``", doc))
        where = init.parent.relative_to(PACKAGE)
        wrong += [f"{where}: {name} not in the docstring" for name in sorted(have - named)]
        wrong += [f"{where}: {name} named but not there" for name in sorted(named & _listed(doc) - have)]
    assert wrong == []


def _listed(doc: str) -> set[str]:
    """The names a docstring's list items start with (``- ``a``, ``b``: ...``)."""
    names: set[str] = set()
    for line in doc.splitlines():
        if line.startswith(("- ``", "  ``")):
            names |= set(re.findall(r"``([a-z_]+/?)``(?=[,:])", line.split(":")[0] + ":"))
    return names


# -- names: each module's face, each type's one home (docs/development.md) -------------------

ARRAY_ALIASES = ("FloatArray", "IntArray", "BoolArray")


def _imported_from_package(path: Path, node: ast.ImportFrom) -> str | None:
    """The package module an ``from ... import`` names (a relative import resolved), else None."""
    if node.level == 0:
        return node.module if (node.module or "").startswith("tumblecal_cli") else None
    here = _module_name(path).split(".")
    base = here if path.stem == "__init__" else here[:-1]
    base = base[: len(base) - (node.level - 1)]
    return ".".join([*base, *([node.module] if node.module else [])])


def _private(name: str) -> bool:
    return name.startswith("_") and not name.startswith("__")


def test_no_module_imports_a_private_name_of_another() -> None:
    """A name another module needs is part of its home's face: public, with a docstring. Neither
    an import (TYPE_CHECKING ones too) nor an attribute of an imported module (``mod._x``) reaches
    for an underscored name of another module."""
    modules = {_module_name(p) for p in _trees()}
    wrong = []
    for path, tree in _trees().items():
        here = _module_name(path)
        imported_modules: set[str] = set()
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and (home := _imported_from_package(path, node)):
                for alias in node.names:
                    if f"{home}.{alias.name}" in modules:
                        imported_modules.add(alias.asname or alias.name)
                    elif _private(alias.name) and home != here:
                        wrong.append(f"{path.relative_to(ROOT)}:{node.lineno}: {alias.name} of {home}")
            elif isinstance(node, ast.Import):
                imported_modules |= {a.asname for a in node.names if a.asname and a.name.startswith("tumblecal_cli")}
        for node in ast.walk(tree):
            if (
                isinstance(node, ast.Attribute)
                and _private(node.attr)
                and isinstance(node.value, ast.Name)
                and node.value.id in imported_modules
            ):
                wrong.append(f"{path.relative_to(ROOT)}:{node.lineno}: {node.value.id}.{node.attr}")
    assert wrong == []


def test_no_module_reads_a_private_attribute_of_another_modules_class() -> None:
    """``obj._x`` where ``obj`` is not ``self``/``cls``, and no class or function of the module
    itself names ``_x``, reaches into another module's object: what it needs is a public name."""
    wrong = []
    for path, tree in _trees().items():
        defined = {"_replace", "_asdict", "_fields", "_make"}  # a NamedTuple's public methods
        outside: set[str] = set()
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                outside |= {
                    (a.asname or a.name).split(".")[0] for a in node.names if not a.name.startswith("tumblecal")
                }
            elif isinstance(node, ast.ImportFrom) and not _imported_from_package(path, node):
                outside |= {a.asname or a.name for a in node.names}  # another library's
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
                defined.add(node.name)
            elif isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id == "self":
                defined.add(node.attr)
            elif isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
                defined.add(node.id)
            elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
                defined.add(node.target.id)
        for node in ast.walk(tree):
            if (
                isinstance(node, ast.Attribute)
                and _private(node.attr)
                and node.attr not in defined
                and not (isinstance(node.value, ast.Name) and node.value.id in ("self", "cls", *outside))
            ):
                wrong.append(f"{path.relative_to(ROOT)}:{node.lineno}: {ast.unparse(node)}")
    assert wrong == []


def test_the_array_aliases_are_defined_once() -> None:
    """FloatArray, IntArray and BoolArray are assigned in one module (core.arrays); the others import them."""
    homes: dict[str, list[str]] = {name: [] for name in ARRAY_ALIASES}
    for path, tree in _trees().items():
        for node in ast.walk(tree):
            targets = (
                node.targets
                if isinstance(node, ast.Assign)
                else [node.target]
                if isinstance(node, ast.AnnAssign)
                else []
            )
            for target in targets:
                if isinstance(target, ast.Name) and target.id in homes:
                    homes[target.id].append(_module_name(path))
    assert homes == {name: ["tumblecal_cli.core.arrays"] for name in ARRAY_ALIASES}


def test_no_class_name_is_defined_in_two_modules() -> None:
    """Each class name says what it is across the package, not only inside its module."""
    seen: dict[str, list[str]] = {}
    for path, tree in _trees().items():
        for node in ast.walk(tree):
            if isinstance(node, ast.ClassDef):
                seen.setdefault(node.name, []).append(str(path.relative_to(PACKAGE)))
    assert {name: homes for name, homes in seen.items() if len(set(homes)) > 1} == {}
