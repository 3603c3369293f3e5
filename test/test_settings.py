"""One declaration per setting: the core's dataclasses declare each field's
unit, help and limits, and the ROS parameters and `fmm` options are made from them."""

import argparse
import dataclasses

import pytest

from fmm_ros.cli import build_parser
from fmm_ros.constants import LEVEL_TOLERANCE_N
from fmm_ros.core.identify.spec import FRICTION_FIT, AxisSpec, FitSpec
from fmm_ros.core.physics.rig import FMM_RIG, PlantRun, Rig
from fmm_ros.core.settings import settings_of
from fmm_ros.core.signal.analysis import ImpactAnalysis, LevelSummary
from fmm_ros.core.signal.config import (
    AnalysisConfig,
    CaptureConfig,
    NominalLevel,
    SensorRanges,
    StreamRules,
)
from fmm_ros.io.textformat import TextFormat
from fmm_ros.report.settings import PageSettings
from fmm_ros.ros.settings import NodeSettings

SETTINGS = (
    CaptureConfig,
    StreamRules,
    AnalysisConfig,
    SensorRanges,
    Rig,
    PlantRun,
    FitSpec,
    AxisSpec,
    TextFormat,
    NodeSettings,
    PageSettings,
)
RESULTS = (ImpactAnalysis, LevelSummary)
# The unit a field's name promises (SI, the unit in the name: `impulse_n_s`).
SUFFIX_UNITS = {
    '_n_s': 'N*s',
    '_m_s': 'm/s',
    '_hz': 'Hz',
    '_kg': 'kg',
    '_n_per_m': 'N/m',
    '_n_s_per_m': 'N*s/m',
    '_m_per_n': 'm/N',
    '_s': 's',
    '_n': 'N',
}


def unit_of_name(name: str) -> str | None:
    for suffix in sorted(SUFFIX_UNITS, key=len, reverse=True):
        if name.endswith(suffix):
            return SUFFIX_UNITS[suffix]
    return None


@pytest.mark.parametrize('cls', SETTINGS + RESULTS, ids=lambda cls: cls.__name__)
def test_every_field_is_declared_with_help_and_the_unit_its_name_promises(cls):
    declared = {item.name: item for item in settings_of(cls)}
    assert set(declared) == {field.name for field in dataclasses.fields(cls)}
    for item in declared.values():
        assert item.help and not item.help[0].islower(), item.name
        assert unit_of_name(item.name) in (None, item.unit), f'{item.name} [{item.unit}]'


@pytest.mark.parametrize('cls', SETTINGS, ids=lambda cls: cls.__name__)
def test_defaults_lie_within_their_limits_and_choices(cls):
    for item in settings_of(cls):
        values = item.default if isinstance(item.default, tuple) else (item.default,)
        for value in values:
            if item.limits and isinstance(value, int | float):
                assert item.limits[0] <= value <= item.limits[1], item.name
            if item.choices and value is not None:  # None: detected or found, not chosen
                assert value in item.choices, item.name


@pytest.mark.slow
def test_the_analyzer_and_rig_parameters_are_the_declared_settings():
    from fmm_ros.ros.common import RIG_PARAMS
    from fmm_ros.ros.nodes.analyzer import PARAMS

    params = {param.name: param for param in (*PARAMS, *RIG_PARAMS)}
    for item in (*settings_of(CaptureConfig), *settings_of(Rig)):
        param = params[item.name]
        assert param.default == item.default and param.limits == item.limits
        assert param.description == item.described
    assert params['level_tolerance_n'].default == LEVEL_TOLERANCE_N
    assert params['force_window_s'].default == 0.0  # None is 0 for a ROS parameter
    assert params['force_window_s'].description.endswith('; 0 for none')


def option_defaults(command: str) -> dict[str, object]:
    action = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    return {
        option: action.default
        for action in action.choices[command]._actions
        for option in action.option_strings
    }


@pytest.mark.slow
def test_the_command_s_options_are_the_declared_settings():
    analyze = option_defaults('analyze')
    assert analyze['--tolerance-n'] == LEVEL_TOLERANCE_N
    assert analyze['--trigger-n'] == CaptureConfig().trigger_level_n
    assert analyze['--rearm-n'] == CaptureConfig().rearm_level_n
    assert analyze['--window-s'] == CaptureConfig().window_s
    assert analyze['--band-limit-hz'] == AnalysisConfig().band_limit_hz
    for command in ('analyze', 'import'):
        for item in settings_of(SensorRanges):
            assert option_defaults(command)[item.option] == item.default, (command, item.name)
    fit = option_defaults('fit')
    for field in dataclasses.fields(Rig):
        assert fit['--' + field.name.replace('_', '-')] == getattr(FMM_RIG, field.name)
    assert fit['--misfit-band-limit-hz'] == FitSpec().band_limit_hz
    assert (fit['--mu-min'], fit['--mu-max']) == FitSpec().mu_bounds
    simulate = option_defaults('simulate')
    for option in ('--integrator', '--x0-m', '--duration-s', '--sample-rate-hz'):
        assert simulate[option] == getattr(PlantRun(), option[2:].replace('-', '_')), option
    assert option_defaults('demo')['--plant-mu'] == PlantRun().mu
    assert option_defaults('demo')['--hits-per-level'] == NodeSettings().hits_per_level
    assert option_defaults('import')['--batch-size'] == NodeSettings().batch_size
    assert option_defaults('identify-friction')['--stiffness-n-per-m'] == 0.0


def test_a_fit_spec_is_changed_by_name_and_refuses_an_unknown_one():
    changed = FRICTION_FIT.but(fit_damping=True)
    assert changed.fit_damping and changed.fit_impulse_scale and not FRICTION_FIT.fit_damping
    with pytest.raises(TypeError, match='fit_dampin'):
        FRICTION_FIT.but(fit_dampin=True)
    assert NominalLevel('low', 450.0).tolerance_n == LEVEL_TOLERANCE_N
