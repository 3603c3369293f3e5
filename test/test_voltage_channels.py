"""Uncalibrated channels: a voltage is analysed in volts, or in SI with a scale in SI per V.

One rule (`fmm_ros.units.channel_factor`) for every command: `fmm identify-friction` and the
lab-file reading of the impact commands give `--force-unit V --force-scale 35.15` the same
meaning (35.15 N per V), and a voltage without a scale is analysed in volts, every figure per V.
The real record is EMPS (test/data/emps/README.md), whose drive force is a controller voltage
times a drive gain of 35.15 N/V.
"""

import json
from pathlib import Path

import numpy as np
import pytest

from fmm_ros.cli import main
from fmm_ros.errors import BadInputError, UnitError
from fmm_ros.io.labfiles import ChannelMapping
from fmm_ros.units import channel_factor

EMPS = Path(__file__).parent / 'data' / 'emps' / 'DATA_EMPS.mat'
GAIN_N_PER_V = 35.15065188
"""EMPS's gtau, as the file holds it."""


@pytest.mark.parametrize(
    ('unit', 'scale', 'expected'),
    [
        ('V', None, (1.0, 'V')),
        ('mV', None, (1e-3, 'V')),
        ('V', 35.15, (35.15, 'N')),
        ('counts', 0.5, (0.5, 'N')),
        (None, 2.0, (2.0, 'N')),
        ('kN', None, (1e3, 'N')),
        (None, None, (1.0, 'N')),
    ],
)
def test_a_channel_becomes_si_or_stays_in_volts(unit, scale, expected) -> None:
    assert channel_factor('force', unit, scale) == pytest.approx(expected)


@pytest.mark.parametrize(
    ('unit', 'scale', 'message'),
    [
        ('kN', 2.0, "force 'F': unit kN already fixes the scale"),
        ('furlong', None, "force 'F': .*'furlong'.*sensor unit"),
        ('V', float('nan'), "force 'F': scale must be a finite non-zero number"),
        ('V', 0.0, "force 'F': scale must be"),
    ],
)
def test_a_bad_unit_or_scale_is_refused_naming_the_channel(unit, scale, message) -> None:
    with pytest.raises(UnitError, match=message):
        channel_factor('force', unit, scale, channel='F')


@pytest.mark.parametrize(('unit', 'scale'), [('V', 35.15), ('counts', 0.25), (None, 4.0)])
def test_lab_files_and_identify_friction_read_a_scale_the_same_way(unit, scale) -> None:
    """The impact commands' lab-file reading gives a stated scale the same factor."""
    lab, _ = ChannelMapping('F', unit, scale).factor('force')
    assert lab == channel_factor('force', unit, scale)[0]
    with pytest.raises(BadInputError, match='already fixes the scale'):
        ChannelMapping('F', 'kN', scale).factor('force')


def _identify(capsys, *extra: str) -> dict:
    args = ['identify-friction', str(EMPS), '--position', 'qm', '--force', 'vir', '--json']
    assert main([*args, *extra]) == 0
    return json.loads(capsys.readouterr().out)


def test_a_voltage_with_its_gain_is_the_force_in_newtons(capsys) -> None:
    by_name = _identify(capsys, '--force-scale', 'gtau')
    by_unit = _identify(capsys, '--force-unit', 'V', '--force-scale', str(GAIN_N_PER_V))
    for key in ('mass_kg', 'coulomb_n', 'viscous_n_s_per_m', 'coulomb_negative_n'):
        assert by_unit[key] == pytest.approx(by_name[key], rel=1e-9), key
    assert by_unit['units']['mass_kg'] == 'kg'
    assert by_unit['units']['force'] == 'N'


def test_a_voltage_without_a_gain_is_analysed_per_volt(capsys) -> None:
    newtons = _identify(capsys, '--force-scale', 'gtau')
    volts = _identify(capsys, '--force-unit', 'V')
    # the model is linear in the force: every force parameter scales by the gain
    for key in ('mass_kg', 'coulomb_n', 'viscous_n_s_per_m', 'offset_n', 'coulomb_positive_n'):
        assert volts[key] * GAIN_N_PER_V == pytest.approx(newtons[key], rel=1e-6), key
    assert volts['relative_error'] == pytest.approx(newtons['relative_error'], rel=1e-6)
    units = volts['units']
    assert units['force'] == 'V' and units['coulomb_n'] == 'V'
    assert units['mass_kg'] == 'V s^2/m'
    assert units['viscous_n_s_per_m'] == 'V s/m'
    assert main(['identify-friction', str(EMPS), '--position', 'qm', '--force', 'vir',
                 '--force-unit', 'V']) == 0  # fmt: skip
    text = capsys.readouterr().out
    assert ' V s^2/m' in text and ' kg' not in text


def test_a_position_in_volts_is_analysed_per_volt(tmp_path: Path, capsys) -> None:
    """A displacement sensor without calibration: the mass is N s^2 per V."""
    t = np.arange(20_000) / 1000.0
    x_m = 0.05 * np.sin(2 * np.pi * 0.5 * t) + 0.02 * np.sin(2 * np.pi * 1.7 * t)
    v = np.gradient(x_m, t)
    a = np.gradient(v, t)
    force = 10.0 * a + 30.0 * v + 5.0 * np.sign(v)
    path = tmp_path / 'axis.npz'
    volts_per_m = 40.0
    np.savez(path, t=t, x=x_m * volts_per_m, force=force)
    args = ['identify-friction', str(path), '--position', 'x', '--force', 'force', '--json']
    assert main([*args, '--motion-unit', 'V']) == 0
    document = json.loads(capsys.readouterr().out)
    assert document['units']['displacement'] == 'V'
    assert document['units']['mass_kg'] == 'N s^2/V'
    assert document['mass_kg'] * volts_per_m == pytest.approx(10.0, rel=0.03)
    assert document['coulomb_n'] == pytest.approx(5.0, rel=0.05)
