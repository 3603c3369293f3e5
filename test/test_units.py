"""The one unit table and the refusal family: every unit converts the same way everywhere."""

import ast
from pathlib import Path

import pytest

from fmm_ros.errors import (
    BadInputError,
    DamagedFileError,
    FitError,
    FmmError,
    Infeasible,
    NoCleanImpactError,
    SelectionError,
    SourceStartTimeout,
    UnitError,
)
from fmm_ros.io.bags.errors import BagDamagedError, MissingTopicError
from fmm_ros.units import QUANTITY_UNITS, SI_UNITS, lookup_unit, si_factor


@pytest.mark.parametrize(
    ('quantity', 'unit', 'factor'),
    [
        ('force', 'kN', 1e3),
        ('force', ' KN ', 1e3),
        ('velocity', 'in/s', 0.0254),
        ('velocity', 'MM/S', 1e-3),
        ('acceleration', 'g', 9.80665),
        ('displacement', 'µm', 1e-6),
        ('time', 'ms', 1e-3),
    ],
)
def test_units_convert_to_si(quantity: str, unit: str, factor: float) -> None:
    assert si_factor(quantity, unit) == pytest.approx(factor)


def test_each_quantity_lists_its_si_unit_first() -> None:
    assert SI_UNITS == {
        'force': 'N',
        'velocity': 'm/s',
        'acceleration': 'm/s^2',
        'displacement': 'm',
        'time': 's',
    }
    for quantity, units in QUANTITY_UNITS.items():
        assert units[SI_UNITS[quantity]] == 1.0


def test_unknown_units_are_refused_by_name() -> None:
    with pytest.raises(UnitError, match=r"'furlong/s'.*known velocity units: m/s"):
        si_factor('velocity', 'furlong/s')
    with pytest.raises(UnitError, match=r"'mm/s' is a velocity unit"):
        si_factor('force', 'mm/s')
    with pytest.raises(UnitError, match='unknown quantity'):
        si_factor('charge', 'C')
    assert lookup_unit('force', None) is None


def test_refusals_form_one_family_of_value_errors() -> None:
    assert issubclass(UnitError, BadInputError)
    for refusal in (BadInputError, DamagedFileError, NoCleanImpactError):
        assert issubclass(refusal, FmmError)
    assert issubclass(FmmError, ValueError)
    assert issubclass(SelectionError, NoCleanImpactError)
    assert issubclass(FitError, FmmError)
    assert issubclass(Infeasible, FmmError)
    assert issubclass(SourceStartTimeout, FmmError) and issubclass(SourceStartTimeout, RuntimeError)
    assert isinstance(BagDamagedError(Path('x'), ['truncated'], 3), DamagedFileError)
    assert issubclass(MissingTopicError, BadInputError)


PACKAGE = Path(__file__).resolve().parents[1] / 'fmm_ros'
FAMILY_MODULES = {PACKAGE / 'errors.py', PACKAGE / 'io' / 'bags' / 'errors.py'}
"""Where the refusal family is declared: errors.py, and the bag I/O members beside the bags."""


def _package_trees():
    for path in sorted(PACKAGE.rglob('*.py')):
        yield path, ast.parse(path.read_text(encoding='utf-8'))


def test_every_public_exception_is_declared_in_the_family_modules() -> None:
    """A public exception class anywhere else is a refusal outside the family."""
    outside = sorted(
        f'{path.relative_to(PACKAGE)}: {node.name}'
        for path, tree in _package_trees()
        if path not in FAMILY_MODULES
        for node in ast.walk(tree)
        if isinstance(node, ast.ClassDef)
        and not node.name.startswith('_')
        and any(ast.unparse(base).endswith(('Error', 'Exception')) for base in node.bases)
    )
    assert outside == []


def test_the_package_raises_no_bare_value_error() -> None:
    """Every refusal is a family member, so a caller tells refused data from a bug."""
    bare = sorted(
        f'{path.relative_to(PACKAGE)}:{node.lineno}'
        for path, tree in _package_trees()
        for node in ast.walk(tree)
        if isinstance(node, ast.Raise)
        and isinstance(node.exc, ast.Call)
        and ast.unparse(node.exc.func) == 'ValueError'
    )
    assert bare == []
