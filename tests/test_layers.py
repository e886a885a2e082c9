"""The layers of DESIGN.md section 3: cli -> io -> core, imports flowing one way.

Each check runs in a fresh interpreter, so what the test process has already imported does
not hide a dependency.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent

PROBE = """
import json, sys
{body}
print(json.dumps(sorted(m for m in {watch!r} if m in sys.modules)))
"""


def imported(body: str, watch: tuple[str, ...]) -> list[str]:
    """Which of ``watch`` are in ``sys.modules`` after running ``body`` in a fresh Python."""
    done = subprocess.run(
        [sys.executable, "-c", PROBE.format(body=body, watch=watch)],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
        cwd=ROOT,
    )
    assert done.returncode == 0, done.stderr
    found: list[str] = json.loads(done.stdout.splitlines()[-1])
    return found


def test_core_imports_numpy_only() -> None:
    assert imported("import tumblecal_cli.core", ("pandas", "pyarrow", "typer", "click", "rich", "yaml")) == []


@pytest.mark.parametrize("module", ["gate", "solvers", "segment"])
def test_core_layer_imports_numpy_only(module: str) -> None:
    assert imported(f"import tumblecal_cli.{module}", ("pandas", "pyarrow", "typer", "click", "rich", "yaml")) == []


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


def test_batch_module_is_light() -> None:
    """A batch worker pays for numpy and Typer on its first unit, not on import; Dask only when asked."""
    assert imported("import tumblecal_cli.batch", ("numpy", "pyarrow", "pandas", "typer", "rich", "distributed")) == []


def test_package_root_is_light() -> None:
    assert imported("import tumblecal_cli", ("numpy", "pyarrow", "pandas", "typer", "rich")) == []


def test_nothing_imports_pandas() -> None:
    """pandas is only the benchmark's baseline: a whole solve and apply run without it."""
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
