"""mu from FMM sessions measured by an accelerometer (`fmm fit` on acceleration records).

The sessions come from `accelerometer_records`, a generator written for the tests (closed-form
Coulomb oscillator, not the product's simulator), with the accelerometer's noise and offset.
"""

import json

import pytest
from accelerometer_records import session, write_csv

from fmm_ros.cli import main


@pytest.mark.slow
@pytest.mark.parametrize('mu, seed', [(0.113, 1), (0.08, 2), (0.15, 3)])
def test_mu_from_an_accelerometer_within_half_a_per_cent(tmp_path, capsys, mu, seed):
    paths = [
        write_csv(tmp_path / f'hit{number}.csv', force, acceleration)
        for number, (force, acceleration) in enumerate(session(mu, seed))
    ]
    assert main(['fit', *map(str, paths), '--json']) == 0
    result = json.loads(capsys.readouterr().out)
    assert result['mu'] == pytest.approx(mu, rel=0.005)
