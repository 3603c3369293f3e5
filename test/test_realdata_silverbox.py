"""A real record the FMM did not make: Silverbox, an electronic Duffing oscillator at 610 Hz.

`../shared/realdata/silverbox/SNLS80mV.mat` (README there: Wigren and Schoukens 2013, MIT via
sysid-neuralnet): the input voltage V1 drives m y'' + d y' + a y + b y^3 = u, the output V2 is
measured; no hits, continuous random excitation, no calibration (everything per V). What is
known: a hardening cubic spring, a resonance near 67 Hz at the lowest amplitudes.

Checked against computations written here with numpy alone: the equation-error least squares
of the linear rig, and the resonance the lowest-amplitude stretch shows as the
peak of its H1 estimate. A record of the same circuit that the tests do not have is stood in
for by independent segments of this one (the noise "arrow" and the multisines; the two
halves), each fitted alone.
"""

import json
import math
from pathlib import Path

import numpy as np
import pytest
import scipy.io

from fmm_ros.cli import main
from fmm_ros.core.identify.whole_record import (
    diagnose_whole_record,
    fit_whole_record,
    foh_matrices,
    simulate_whole_record,
)
from fmm_ros.errors import BadInputError

SILVERBOX = (
    Path(__file__).resolve().parents[1].parent / 'shared' / 'realdata' / 'silverbox'
) / 'SNLS80mV.mat'
RATE_HZ = 1e7 / 2**14
ARROW_END = 40_700
"""The noise 'arrow head' ends about here; ten multisines follow (README)."""


@pytest.fixture(scope='module')
def record() -> tuple[np.ndarray, np.ndarray]:
    """Input and output voltage [V]."""
    data = scipy.io.loadmat(SILVERBOX)
    return data['V1'].ravel().astype(float), data['V2'].ravel().astype(float)


def equation_error_resonance(u: np.ndarray, y: np.ndarray) -> float:
    """sqrt(k/m)/2 pi from least squares on m y'' + c y' + k y + f0 = u (central differences)."""
    h = 1.0 / RATE_HZ
    acceleration = (y[2:] - 2.0 * y[1:-1] + y[:-2]) / h**2
    velocity = (y[2:] - y[:-2]) / (2.0 * h)
    columns = np.column_stack((acceleration, velocity, y[1:-1], np.ones(y.size - 2)))
    m, _, k, _ = np.linalg.lstsq(columns, u[1:-1], rcond=None)[0]
    return math.sqrt(k / m) / (2.0 * math.pi)


def lowest_level_h1_peak(u: np.ndarray, y: np.ndarray) -> float:
    """Peak of |H1| = |sum Y U*| / sum |U|^2 over 2048-sample Hann blocks of the first 8192
    samples of the arrow, where the amplitude is smallest (the cubic spring matters least)."""
    size = 2048
    window = np.hanning(size)
    blocks = [slice(start, start + size) for start in range(0, 8192 - size + 1, size // 2)]
    uu = sum(np.abs(np.fft.rfft(window * (u[b] - u[b].mean()))) ** 2 for b in blocks)
    yu = sum(
        np.fft.rfft(window * (y[b] - y[b].mean()))
        * np.conj(np.fft.rfft(window * (u[b] - u[b].mean())))
        for b in blocks
    )
    frequency = np.fft.rfftfreq(size, 1.0 / RATE_HZ)
    band = (frequency > 30.0) & (frequency < 120.0)
    return float(frequency[band][np.argmax(np.abs(yu / uu)[band])])


def test_the_first_order_hold_is_exact_for_a_ramp() -> None:
    """Against the closed-form response of m x'' + k x = t (no damping): x = (t - sin(wt)/w)/k."""
    m, k, h = 2.0, 800.0, 0.01
    phi, gamma0, gamma1 = foh_matrices(m, 0.0, k, h)
    state = np.zeros(2)
    for n in range(50):
        state = phi @ state + gamma0 * (n * h) + gamma1 * ((n + 1) * h)
    t, w = 50 * h, math.sqrt(k / m)
    assert state[0] == pytest.approx((t - math.sin(w * t) / w) / k, rel=1e-10)
    force = np.arange(51) * h
    x = simulate_whole_record(force, 1.0 / h, {'mass': m, 'damping': 0.0, 'stiffness': k})
    assert x[-1] == pytest.approx((t - math.sin(w * t) / w) / k, rel=1e-10)


@pytest.mark.slow
def test_silverbox_names_a_hardening_cubic_spring_and_no_friction(record) -> None:
    u, y = record
    result = diagnose_whole_record(u, y, RATE_HZ)
    assert result.named == ('cubic_stiffness',)
    final = result.final
    k3 = final.values['cubic_stiffness']
    assert k3 > 0.0 and k3 > 10.0 * final.stderr['cubic_stiffness']
    assert 'coulomb_friction' in result.why
    # the gap halves (it falls tenfold)
    assert final.gap <= 0.5 * result.base.gap
    # the linear part is the small-amplitude resonance: within 3 % of the lowest level's H1
    # peak and of the equation-error estimate on raw central differences (68.0 Hz here; a
    # low-pass before differentiating moves it to 63 Hz: the equation error's noise bias)
    resonance = final.natural_frequency_hz
    assert resonance == pytest.approx(lowest_level_h1_peak(u, y), rel=0.03)
    independent = equation_error_resonance(u, y)
    assert 56.0 < independent < 68.0
    assert resonance == pytest.approx(independent, rel=0.03)


@pytest.mark.slow
@pytest.mark.parametrize(
    ('first', 'second'),
    [
        (slice(0, ARROW_END), slice(ARROW_END, None)),
        (slice(0, 65_536), slice(65_536, None)),
    ],
    ids=['arrow-vs-multisines', 'halves'],
)
def test_k3_over_k_is_the_same_in_independent_segments(record, first, second) -> None:
    """A stand-in for another record of the same circuit: each segment fitted alone."""
    u, y = record
    ratios = []
    for part in (first, second):
        fit = fit_whole_record(u[part], y[part], RATE_HZ, terms=('cubic_stiffness',))
        ratios.append(fit.values['cubic_stiffness'] / fit.values['stiffness'])
    assert min(ratios) > 0.0
    assert ratios[0] == pytest.approx(ratios[1], rel=0.25)


def test_bad_whole_records_are_refused_by_name() -> None:
    with pytest.raises(BadInputError, match='not finite at sample 3'):
        fit_whole_record(np.r_[np.zeros(3), np.nan, np.zeros(200)], np.ones(204), 100.0)
    with pytest.raises(BadInputError, match='one length'):
        fit_whole_record(np.zeros(200), np.zeros(100), 100.0)
    with pytest.raises(BadInputError, match='sample rate'):
        fit_whole_record(np.zeros(200), np.zeros(200), -1.0)
    with pytest.raises(BadInputError, match="term 'magic'"):
        fit_whole_record(np.zeros(200), np.arange(200.0), 100.0, terms=('magic',))


CHANNELS = ['--force', 'V1', '--force-unit', 'V', '--displacement', 'V2']
CHANNELS += ['--displacement-unit', 'V', '--sample-rate-hz', str(RATE_HZ)]


@pytest.mark.slow
def test_fmm_diagnose_whole_record_fits_the_rig_per_volt(capsys) -> None:
    args = ['diagnose', str(SILVERBOX), '--whole-record', '--fit-rig', *CHANNELS, '--json']
    assert main(args) == 0
    document = json.loads(capsys.readouterr().out)
    assert document['named'] == ['cubic_stiffness']
    assert document['fits_record'] is True
    rig = document['rig']
    assert set(rig) >= {'mass_kg', 'damping_n_s_per_m', 'stiffness_n_per_m'}
    assert rig['mass_kg'] > 0.0 and rig['stiffness_n_per_m_stderr'] > 0.0
    resonance = math.sqrt(rig['stiffness_n_per_m'] / rig['mass_kg']) / (2.0 * math.pi)
    assert resonance == pytest.approx(document['natural_frequency_hz'])
    cubic = document['terms']['cubic_stiffness']
    assert cubic['cubic_stiffness_n_per_m3'] > 0.0
    assert document['units']['cubic_stiffness_n_per_m3'] == 'V/V^3'
    assert document['units']['mass_kg'] == 'V s^2/V'
    assert document['gap_after'] <= 0.5 * document['gap_before']
    assert 'coulomb_friction' in document['not_named']


@pytest.mark.parametrize(
    ('extra', 'message'),
    [
        (['--force', 'V1', '--sample-rate-hz', '610'], 'force and displacement channels named'),
        (['--force', 'V1', '--displacement', 'V2'], 'no time base'),
        ([*CHANNELS[:-2], '--sample-rate-hz', '-3'], 'sample rate must be positive'),
        (['--force', 'V1', '--force-unit', 'furlong', *CHANNELS[4:]], "force 'V1'"),
        (['--force', 'V9', *CHANNELS[2:]], "'V9'"),
    ],
)
def test_bad_whole_record_input_is_named(extra, message, capsys) -> None:
    assert main(['identify-rig', str(SILVERBOX), '--whole-record', *extra]) == 2
    assert message in capsys.readouterr().err
