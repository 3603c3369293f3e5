"""`fmm analyze` on lab-chain records from a held-out generator, against a whole-record DFT.

The records come from `heldout` (event-located motion, half-sine and Hertzian hits with a
sub-sample onset, a force channel with a 0.22 N zero offset, drift and hum, an 8th-order
anti-alias filter, a 16-bit ADC): a world the analysis was never tuned on. Every accepted
hit must carry its headline numbers, every session its linearity R^2, and the peak |X/F| and
f_n must agree with an independent computation with numpy alone (test/dft_reference.py): the DFT of
each whole record, offsets taken off, the receptance V / (F i omega) and its peak. The same
on `newmark` (held out too), whose quietest hits ring too briefly to time and are read at
their DFT peak, and on
`karnopp` (held out, written later: a Hunt-Crossley hammer striking the moving rig, a Bessel
chain, a multiplexed ADC's skew, random-walk drift on the velocity).
"""

import dataclasses
import json
import math

import numpy as np
import pytest
from dft_reference import independent_peak
from heldout.karnopp import KARNOPP
from heldout.lab import EVENTS, Effects, session
from heldout.newmark import NEWMARK

from fmm_ros.cli import main
from fmm_ros.core.signal.analysis import analyze_impact
from fmm_ros.core.signal.config import FLAGS, UNDETERMINED
from fmm_ros.core.signal.records import ImpactRecord, write_impact_csv
from fmm_ros.report.session import FLAG_MEANINGS

SESSIONS = 2
RECORD_S = 33.0


def analyzed(records, onsets_s, impulses_n_s, tmp_path, capsys, name: str) -> tuple[dict, list]:
    """`fmm analyze --json` of one session's records: (its report, what disagrees).

    Every accepted hit must carry its headline numbers, its peak |X/F| within 5 % and f_n
    within 4 % of `independent_peak`, its impulse within 1 % of the truth; a hit not
    accepted must say why (a flag).
    """
    paths = []
    for hit, record in enumerate(records):
        path = tmp_path / f'{name}_hit{hit}.csv'
        write_impact_csv(path, record.force_n, record.velocity_m_s, record.sample_rate_hz)
        paths.append(path)
    assert main(['analyze', *map(str, paths), '--json', '--paper-levels']) == 0
    report = json.loads(capsys.readouterr().out)
    failures = []
    for record, onset, impulse, impact in zip(
        records, onsets_s, impulses_n_s, report['impacts'], strict=True
    ):
        if not impact['accepted']:
            assert impact['flags'], impact
            continue
        assert impact['peak_receptance_m_per_n'] is not None, impact
        assert impact['natural_frequency_hz'] is not None, impact
        peak, natural = independent_peak(
            record.force_n, record.velocity_m_s, record.sample_rate_hz, onset
        )
        if abs(impact['peak_receptance_m_per_n'] / peak - 1) > 0.05:
            failures.append(('|X/F|', impact['file'], impact['peak_receptance_m_per_n'], peak))
        if abs(impact['natural_frequency_hz'] / natural - 1) > 0.04:
            failures.append(('f_n', impact['file'], impact['natural_frequency_hz'], natural))
        if abs(impact['impulse_n_s'] / impulse - 1) > 0.01:
            failures.append(('impulse', impact['file'], impact['impulse_n_s'], impulse))
    return report, failures


@pytest.mark.slow
def test_analyze_holds_on_lab_chain_records_of_a_held_out_world(tmp_path, capsys):
    failures = []
    for index in range(SESSIONS):
        rng = np.random.default_rng([24, index])
        records = session(
            EVENTS, Effects(), float(rng.uniform(0.09, 0.15)), rng, duration_s=RECORD_S
        )
        report, wrong = analyzed(
            records,
            [record.hit.onset_s for record in records],
            [record.hit.impulse_n_s for record in records],
            tmp_path,
            capsys,
            f's{index}',
        )
        assert all(impact['accepted'] for impact in report['impacts']), report['impacts']
        assert report['linearity']['r2'] is not None, report['linearity']
        failures += wrong
    assert failures == []


HARD_TIP_WORLDS = {'newmark': (NEWMARK, 'hammer'), 'karnopp': (KARNOPP, 'strike')}
"""Held-out worlds whose stiff tips strike 450 N hits that barely swing the rig: each world,
and the field of its records that holds the hit (its onset_s and impulse_n_s)."""


@pytest.mark.slow
@pytest.mark.parametrize('name', sorted(HARD_TIP_WORLDS))
def test_analyze_holds_on_worlds_whose_stiff_tips_barely_swing_the_rig(name, tmp_path, capsys):
    """`newmark` (a Kelvin-Voigt tip whose force jumps at the touch, a settling
    charge-amplifier zero, floor vibration, 10 or 16.384 kHz) and `karnopp` (its first FRFs: a
    Hunt-Crossley hammer striking the moving rig, a 4th-order Bessel chain at 10 or 20.48 kHz,
    16 bits, a random walk on the velocity), both held out. A stiff tip's 450 N hit (0.30 N s)
    swings the rig two or three half cycles before it sticks, too few reversals to time: its
    f_n is read at its DFT peak (`frf.dft_peak_frequency`) and it is accepted. Every hit
    agrees with the independent DFT; every session has its R^2."""
    world, field = HARD_TIP_WORLDS[name]
    world = dataclasses.replace(world, duration_s=RECORD_S)
    failures = []
    for index in range(SESSIONS):
        rng = np.random.default_rng([24, index])
        records = world.session(
            Effects(), float(rng.uniform(0.09, 0.15)), rng, (450.0, 1000.0, 1450.0), centred=True
        )
        hits = [getattr(record, field) for record in records]
        report, wrong = analyzed(
            records,
            [hit.onset_s for hit in hits],
            [hit.impulse_n_s for hit in hits],
            tmp_path,
            capsys,
            f'{name}{index}',
        )
        failures += wrong
        assert all(impact['accepted'] for impact in report['impacts']), report['impacts']
        assert report['linearity']['r2'] is not None, report['linearity']
    assert failures == []


def test_a_hit_without_a_headline_number_is_flagged_and_never_accepted():
    """A response that never reverses has no f_n (its spectrum peaks at DC, not in the band):
    the hit is flagged 'undetermined'."""
    rate = 10_000.0
    t = np.arange(int(6 * rate)) / rate
    force = np.where((t > 1.0) & (t < 1.003), 1000.0 * np.sin(np.pi * (t - 1.0) / 0.003), 0.0)
    velocity = np.where(t > 1.003, 0.2 * np.exp(-(t - 1.003) / 0.1), 0.0)
    noise = np.random.default_rng(24).normal(size=(2, t.size))
    record = ImpactRecord(force + 0.2 * noise[0], velocity + 1e-4 * noise[1], rate)
    result = analyze_impact(record)
    assert math.isnan(result.natural_frequency_hz)
    assert result.flags == (UNDETERMINED,) and not result.accepted
    assert UNDETERMINED in FLAGS and UNDETERMINED in FLAG_MEANINGS
