"""Reading one 33 s impact (2 x 330,000 samples at 10 kHz) through the input layer, per format.

Run: .venv/bin/python benchmarks/bench_inputs.py [--repeats R]

The same samples are written as fmm's own CSV, a German Excel export (semicolons, decimal
commas, a units row, cp1252), MATLAB v5, MATLAB v7.3 and TDMS, each by its own library, and
read by `fmm_ros.workflows.inputs.read_inputs` (content sniffed, layout detected, channels
resolved from the units the file states). The baseline, in the same run, is the plain reader
of fmm's own CSV format (`core.signal.records.read_impact_csv`: one np.loadtxt of a file
whose layout is known); the ratio is what detection and the general path cost.
"""

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

import h5py
import numpy as np
import scipy.io
from nptdms import ChannelObject, GroupObject, TdmsWriter
from results_file import QUICK_HELP, recorded

from fmm_ros.core.signal.records import read_impact_csv, write_impact_csv
from fmm_ros.workflows.inputs import read_inputs

RATE_HZ = 10_000.0
SECONDS = 33.0


def write_files(folder: Path) -> dict[str, Path]:
    """The same noisy record in five formats."""
    rng = np.random.default_rng(0)
    n = int(SECONDS * RATE_HZ)
    force, velocity = rng.normal(0, 1, n), rng.normal(0, 1e-3, n)
    time_s = np.arange(n) / RATE_HZ
    files = {'fmm CSV': folder / 'hit.csv'}
    write_impact_csv(files['fmm CSV'], force, velocity, RATE_HZ)
    files['German Excel CSV'] = folder / 'Messung.csv'
    rows = '\n'.join(
        f'{t:.4f};{f:.6f};{v * 1e3:.6f}'.replace('.', ',')
        for t, f, v in zip(time_s, force, velocity, strict=True)
    )
    files['German Excel CSV'].write_bytes(
        ('Zeit;Hammerkraft;Geschwindigkeit\ns;N;mm/s\n' + rows).encode('cp1252')
    )
    files['MATLAB v5'] = folder / 'hit.mat'
    scipy.io.savemat(
        files['MATLAB v5'], {'force_n': force, 'velocity_m_s': velocity, 'sample_rate_hz': RATE_HZ}
    )
    files['MATLAB v7.3'] = folder / 'hit73.mat'
    with h5py.File(files['MATLAB v7.3'], 'w', userblock_size=512) as hdf:
        hdf['force_n'], hdf['velocity_m_s'] = force[None, :], velocity[None, :]
        hdf['sample_rate_hz'] = np.array([[RATE_HZ]])
    files['TDMS'] = folder / 'hit.tdms'
    common = {'wf_increment': 1 / RATE_HZ}
    with TdmsWriter(files['TDMS']) as writer:
        writer.write_segment(
            [
                GroupObject('Impact'),
                ChannelObject('Impact', 'Hammer', force, {**common, 'unit_string': 'N'}),
                ChannelObject('Impact', 'LDV', velocity, {**common, 'unit_string': 'm/s'}),
            ]
        )
    return files


def median_s(action, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        action()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--repeats', type=int, default=5)
    parser.add_argument('--quick', action='store_true', help=QUICK_HELP)
    args = parser.parse_args()
    if args.quick:
        args.repeats = 1
    with tempfile.TemporaryDirectory(prefix='bench_inputs_') as folder:
        files = write_files(Path(folder))
        read_inputs([files['German Excel CSV']])  # imports (clevercsv, chardet), page cache
        baseline = median_s(lambda: read_impact_csv(files['fmm CSV']), args.repeats)
        print(f'one {SECONDS:g} s impact at {RATE_HZ:g} Hz, median of {args.repeats} runs\n')
        print(f'{"baseline: read_impact_csv of fmm CSV":44s} {baseline * 1e3:8.0f} ms')
        for name, path in files.items():
            seconds = median_s(lambda path=path: read_inputs([path]), args.repeats)
            print(
                f'{"read_inputs, " + name:44s} {seconds * 1e3:8.0f} ms (x{seconds / baseline:.2f})'
            )
    return 0


if __name__ == '__main__':
    with recorded('bench_inputs', quick='--quick' in sys.argv):
        raise SystemExit(main())
