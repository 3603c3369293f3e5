"""Any response sensor: velocity, acceleration or displacement give one FRF in three forms.

One motion, written here in closed form (a 50 Hz mode, 2 % damping, struck by an impulse at
0.1 s), is measured by each of the three sensors; `fmm analyze` must give the same H1 from
each (accelerance, mobility and receptance), read them by their column names, through a bag
as through the file, and refuse what it cannot use by name.
"""

import contextlib
import io
import json

import numpy as np
import pytest

from fmm_ros.cli import main
from fmm_ros.core.signal.response import checked_quantity, convert_spectrum
from fmm_ros.errors import BadInputError

RATE_HZ = 10_000.0
MODE_HZ, ZETA, MASS_KG = 50.0, 0.02, 2.0
IMPULSE_N_S, HIT_S, PULSE_S = 0.5, 0.1, 0.002
BAND_HZ = 200.0
COLUMNS = {
    'velocity': 'velocity_m_s',
    'acceleration': 'acceleration_m_s2',
    'displacement': 'displacement_m',
}


def motion() -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Force [N], a half-sine pulse, and the mode's x, v, a: the pulse convolved with the
    closed-form impulse responses (midpoint rule, 400 points over the pulse), plus noise."""
    time_s = np.arange(int(2.0 * RATE_HZ)) / RATE_HZ
    peak = IMPULSE_N_S * np.pi / (2 * PULSE_S)

    def pulse(t):
        phase = (t - HIT_S) / PULSE_S
        return np.where((phase > 0) & (phase < 1), peak * np.sin(np.pi * np.clip(phase, 0, 1)), 0.0)

    omega = 2 * np.pi * MODE_HZ
    sigma, omega_d = ZETA * omega, omega * np.sqrt(1 - ZETA**2)
    step = PULSE_S / 400
    source = HIT_S + (np.arange(400) + 0.5) * step
    lag = time_s[:, None] - source[None, :]
    decay = np.where(lag > 0, np.exp(-sigma * np.clip(lag, 0, None)), 0.0) / MASS_KG
    cos, sin = np.cos(omega_d * lag), np.sin(omega_d * lag)
    kernels = {
        'displacement': decay * sin / omega_d,
        'velocity': decay * (cos - sigma / omega_d * sin),
        'acceleration': decay * (-2 * sigma * cos + (sigma**2 - omega_d**2) / omega_d * sin),
    }
    force = pulse(time_s)
    rng = np.random.default_rng(5)
    responses = {}
    for quantity, kernel in kernels.items():
        response = kernel @ (pulse(source) * step)
        if quantity == 'acceleration':
            response += force / MASS_KG  # the hammer's own push: m a = f - c v - k x
        noise = 1e-5 * np.max(np.abs(response))
        responses[quantity] = response + rng.normal(0, noise, response.size)
    return force + rng.normal(0, 0.01, force.size), responses


def analyze_json(*args) -> dict:
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(['analyze', *map(str, args), '--json', '-q']) == 0
    return json.loads(out.getvalue())


@pytest.fixture(scope='module')
def sensor_files(tmp_path_factory):
    folder = tmp_path_factory.mktemp('sensors')
    force, responses = motion()
    time_s = np.arange(force.size) / RATE_HZ
    paths = {}
    for quantity, column in COLUMNS.items():
        paths[quantity] = folder / f'{quantity}.csv'
        np.savetxt(
            paths[quantity],
            np.column_stack((time_s, force, responses[quantity])),
            delimiter=',',
            header=f'time_s,force_n,{column}',
            comments='',
            fmt='%.17g',
        )
    return folder, paths


@pytest.mark.slow
def test_three_sensors_give_one_frf_in_three_forms(sensor_files):
    folder, paths = sensor_files
    tables = {}
    for quantity, path in paths.items():
        out = folder / f'{quantity}_levels.csv'
        report = analyze_json(path, '--band-limit-hz', BAND_HZ, '-o', out)
        assert report['impacts'][0]['flags'] == []
        assert report['impacts'][0]['impulse_n_s'] == pytest.approx(IMPULSE_N_S, rel=3e-3)
        table = np.genfromtxt(out, delimiter=',', names=True)
        tables[quantity] = table
    frequency = tables['velocity']['frequency_hz']
    band = (frequency > 30) & (frequency < 150)  # below, an accelerometer's noise over omega^2
    omega = 2j * np.pi * frequency[band]
    exact = 1 / (
        MASS_KG * ((2 * np.pi * MODE_HZ) ** 2 + 2 * ZETA * 2 * np.pi * MODE_HZ * omega + omega**2)
    )
    for form, factor in (('receptance', 1), ('mobility', omega), ('accelerance', omega**2)):
        for quantity, table in tables.items():
            h1 = table[f'level_1_h1_{form}_real'] + 1j * table[f'level_1_h1_{form}_imag']
            # The same motion from each sensor; the mode's own FRF (pulse and sampling aside).
            reference = (
                tables['velocity'][f'level_1_h1_{form}_real']
                + 1j * tables['velocity'][f'level_1_h1_{form}_imag']
            )
            np.testing.assert_allclose(
                h1[band], reference[band], rtol=5e-3, err_msg=f'{quantity} {form}'
            )
            np.testing.assert_allclose(
                h1[band], exact * factor, rtol=0.02, err_msg=f'{quantity} {form}'
            )


@pytest.mark.slow
def test_an_accelerometer_bag_gives_what_its_file_gives(sensor_files, capsys):
    folder, paths = sensor_files
    bag = folder / 'acceleration_bag'
    assert main(['import', str(paths['acceleration']), '-o', str(bag), '-q']) == 0
    capsys.readouterr()
    from_file = analyze_json(paths['acceleration'], '--window-s', '1.5', '--continuous')
    from_bag = analyze_json(bag, '--window-s', '1.5')
    assert len(from_bag['impacts']) == 1
    assert from_bag['impacts'][0]['flags'] == from_file['impacts'][0]['flags']
    for key in ('impulse_n_s', 'peak_force_n', 'peak_receptance_m_per_n'):
        assert from_bag['impacts'][0][key] == pytest.approx(from_file['impacts'][0][key], rel=1e-9)


def test_a_channel_of_an_unknown_kind_is_refused_by_name(tmp_path, capsys):
    with pytest.raises(BadInputError, match="unknown kind 'jerk'"):
        checked_quantity('jerk')
    mapping = tmp_path / 'map.yaml'
    mapping.write_text('force: {name: F, unit: N}\njerk: {name: J, unit: m/s^3}\n')
    path = tmp_path / 'f.csv'
    path.write_text('t,F,J\n0,0,0\n0.001,1,1\n')
    assert main(['analyze', str(path), '-m', str(mapping)]) == 2
    assert 'unknown mapping keys: jerk' in capsys.readouterr().err


def test_fmm_simulate_output_is_analysed_by_its_velocity(tmp_path, capsys):
    """`fmm simulate -o` writes velocity_m_s and displacement_m: the velocity is the response."""
    time_s = np.arange(30_000) / 10_000.0
    phase = (time_s - 0.5) / 0.003
    force = np.where((phase > 0) & (phase < 1), 1000 * np.sin(np.pi * np.clip(phase, 0, 1)), 0)
    force_csv = tmp_path / 'force.csv'
    np.savetxt(force_csv, np.column_stack((time_s, force)), delimiter=',', comments='',
               header='time_s,force_n')  # fmt: skip
    simulated = tmp_path / 'sim.csv'
    assert main(['simulate', '--force-csv', str(force_csv), '-o', str(simulated), '--json']) == 0
    capsys.readouterr()
    assert main(['analyze', str(simulated), '--json']) == 0
    (impact,) = json.loads(capsys.readouterr().out)['impacts']
    assert impact['impulse_n_s'] == pytest.approx(2 * 1000 * 0.003 / np.pi, rel=1e-3)


def test_an_accelerometer_named_as_the_velocity_is_pointed_to_its_flag(tmp_path, capsys):
    path = tmp_path / 'hit.csv'
    path.write_text('time_s,force_n,acceleration_m_s2\n0,0,0\n0.001,1,1\n')
    assert main(['analyze', str(path), '--velocity', 'acceleration_m_s2']) == 2
    error = capsys.readouterr().err
    assert "unit 'm/s^2' is not a velocity unit" in error
    assert '--acceleration acceleration_m_s2' in error


def test_a_position_without_a_time_base_is_refused(tmp_path, capsys):
    path = tmp_path / 'position.csv'
    path.write_text('force_n,displacement_m\n' + '\n'.join(f'{i},{i * 1e-6}' for i in range(50)))
    assert main(['analyze', str(path)]) == 2
    err = capsys.readouterr().err
    assert 'no sample rate' in err and 'displacement' in err


def test_spectra_convert_exactly_between_the_quantities():
    frequency = np.array([0.0, 1.0, 10.0])
    spectrum = np.array([2.0, 1.0 + 1j, -3.0j])
    omega = 2j * np.pi * frequency
    velocity = convert_spectrum(spectrum, frequency, 'acceleration', 'velocity')
    np.testing.assert_allclose(velocity[1:], spectrum[1:] / omega[1:])
    assert velocity[0] == 0  # DC holds no integrated quantity
    back = convert_spectrum(velocity, frequency, 'velocity', 'acceleration')
    np.testing.assert_allclose(back[1:], spectrum[1:])
    np.testing.assert_allclose(
        convert_spectrum(spectrum, frequency, 'displacement', 'acceleration'), spectrum * omega**2
    )
