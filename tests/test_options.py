"""solve's options, from the command line and from Python, reach the pipeline grouped the same way."""

from __future__ import annotations

import inspect

import pytest

from tumblecal_cli.cli.solve import CLI_ONLY, solve
from tumblecal_cli.errors import InputError
from tumblecal_cli.io.readspec import Dialect, ReadSpec
from tumblecal_cli.pipeline.options import FLAT, CheckOptions, LimitOptions, LogOptions, SolveOptions, UnitOptions

OPTION_NAMES = tuple(name for name in inspect.signature(solve).parameters if name not in CLI_ONLY)


def solve_options(**given: object) -> SolveOptions:
    """What the command makes of its parameters: SolveOptions.of, by name."""
    return SolveOptions.of(given)


def test_every_option_of_solve_options_is_a_parameter_of_solve_and_of_the_python_api() -> None:
    """The command passes its parameters to SolveOptions.of by name; the Python API's keywords are FLAT's."""
    assert set(OPTION_NAMES) <= set(inspect.signature(solve).parameters)
    assert set(OPTION_NAMES) == set(FLAT)


def test_the_command_line_and_python_build_the_same_options() -> None:
    given: dict[str, object] = {
        "method": "six-pose",
        "sensor": "magnetometer",
        "reference": 48.0,
        "columns": "mx,my,mz",
        "no_header": True,
        "time_unit": "ms",
        "rate": 100.0,
        "skip_rows": 2,
        "decimal": ",",
        "drop_incomplete": True,
        "window": 0.5,
        "pose_column": "face",
        "max_noise": 0.01,
        "no_check": ["moved"],
        "limits": "limits.yaml",
        "max_offset": "0.1",
        "serial": "A17",
        "meta": ["lot=7"],
    }
    defaults = {
        name: p.default
        for name, p in inspect.signature(solve).parameters.items()
        if name in OPTION_NAMES and name not in given
    }
    built = solve_options(**{**{k: getattr(v, "default", v) for k, v in defaults.items()}, **given})
    via_python = SolveOptions.of(given)
    assert (
        built.read
        == via_python.read
        == ReadSpec("magnetometer", ("mx", "my", "mz"), True, None, "ms", 100.0, Dialect(2, ",", True))
    )
    assert built.log == via_python.log == LogOptions(window=0.5, pose_column="face")
    assert built.checks.max_noise == via_python.checks.max_noise == 0.01
    assert tuple(built.checks.no_check) == tuple(via_python.checks.no_check) == ("moved",)
    assert built.limits == via_python.limits == LimitOptions("limits.yaml", "0.1")
    assert built.unit.serial == via_python.unit.serial == "A17"
    assert (built.method, built.reference) == (via_python.method, via_python.reference) == ("six-pose", 48.0)
    assert via_python.flat()["max_noise"] == 0.01
    assert isinstance(built.checks, CheckOptions)
    assert isinstance(built.unit, UnitOptions)


def test_an_unknown_option_from_python_is_a_type_error() -> None:
    with pytest.raises(TypeError, match="no_such_option"):
        SolveOptions.of({"no_such_option": 1})


@pytest.mark.parametrize(
    ("given", "message"),
    [
        ({"min_samples": None}, "--min-samples takes a whole number of 1 or more, got None"),
        ({"decimal": "x"}, "--decimal: 'x' is not one of ., ,"),
        ({"method": "bogus", "skip_rows": -1}, "--method: 'bogus' is not one of"),
        ({"sensor": "bogus", "skip_rows": True}, "--sensor: 'bogus' is not one of"),
    ],
)
def test_options_from_python_are_judged_as_before_in_the_same_order(given: dict[str, object], message: str) -> None:
    """An explicit None is given, not the default; a choice is judged before the file's shape."""
    from tumblecal_cli.pipeline.options import checked

    with pytest.raises(InputError) as err:
        checked(SolveOptions.of(given))
    assert err.value.message.startswith(message)


def test_an_unknown_option_names_the_options_class_as_python_did() -> None:
    with pytest.raises(TypeError, match=r"^SolveOptions.__init__\(\) got an unexpected keyword argument 'foo'$"):
        SolveOptions.of({"foo": 1})


def test_the_python_api_keywords_are_the_mappers_flat_names() -> None:
    """SolveKeywords (solve's and solve_log's ``**options``) names every flat option of the one
    mapper, SolveOptions.of, and no other; its read keywords are a ReadSpec's."""
    from tumblecal_cli.io.readspec import READ_NAMES, ReadKeywords
    from tumblecal_cli.pipeline.options import SolveKeywords
    from tumblecal_cli.pipeline.solve import solving

    assert set(SolveKeywords.__annotations__) == set(FLAT)
    assert set(ReadKeywords.__annotations__) == set(READ_NAMES) <= set(FLAT)
    for function in (solving.solve, solving.solve_log):
        assert inspect.signature(function).parameters["options"].annotation == "Unpack[SolveKeywords]"


def test_each_option_of_the_command_is_a_flat_name_or_the_command_lines_own() -> None:
    """Every ``tumblecal solve`` parameter is a flat option of SolveOptions.of, or one of CLI_ONLY
    (what to read, where to write, what to print), never both; batch takes the flat ones."""
    from tumblecal_cli.cli.batch import batch

    parameters = set(inspect.signature(solve).parameters)
    assert set(CLI_ONLY) <= parameters
    assert set(CLI_ONLY).isdisjoint(FLAT)
    assert parameters - set(CLI_ONLY) == set(FLAT)
    assert set(FLAT) - {"serial"} <= set(inspect.signature(batch).parameters)


def test_the_command_lines_defaults_are_the_python_apis() -> None:
    """Each option left out on the command line maps to what the Python API leaves out: the
    defaults of SolveOptions (a repeatable option not given, None, is none)."""
    defaults = {name: p.default for name, p in inspect.signature(solve).parameters.items() if name in FLAT}
    assert SolveOptions.of(defaults) == SolveOptions()
    assert SolveOptions.of({"meta": None, "no_check": None}).unit.meta == ()


def test_the_read_options_are_one_read_spec() -> None:
    """solve's read options reach the pipeline as io.readspec.read_spec makes them, for any command."""
    from tumblecal_cli.io.readspec import ReadKeywords, read_spec

    given: ReadKeywords = {"sensor": "gyroscope", "columns": "gx,gy,gz", "time_unit": "ms", "skip_rows": 1}
    spec = ReadSpec("gyroscope", ("gx", "gy", "gz"), time_unit="ms", dialect=Dialect(1))
    assert SolveOptions.of(given).read == read_spec(given) == spec
