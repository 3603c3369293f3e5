"""Fuzzing the file readers: valid seed files, mutations of them, and a guarded runner.

fmm reads untrusted files on these paths, each run here exactly as a user runs it (the `fmm`
entry point, in-process):

- `fmm analyze impact.csv` (the per-impact CSV, `read_impact_csv`);
- `fmm import FILE -o BAG` of CSV, NPZ, MATLAB v5 and v7.3 (HDF5) and TDMS files;
- `fmm analyze BAG` and `fmm bag-info BAG` of MCAP and sqlite3 bags of two acquisitions (as
  `fmm import` writes them; the storage file and metadata.yaml mutated).

fmm writes UFF 58 (frf_files.py) but reads no UFF file, so there is no UFF reader to fuzz.

Mutations (`mutate`, deterministic in a seed): truncation; 1-16 flipped bits; a zeroed block
of 1-4096 bytes; a wrong header (the first bytes replaced by another format's magic, or
junk); a huge declared length (a length or size field of the format's structure, found by
walking it where we can, else a random aligned word, set to 2^31-1, 2^32-1 or 2^63-1); and for
text, a line made junk, a number made huge and a line made 1 MB long.

`run_cases` runs each case in a child forked from a warm worker process (every reader
imported and exercised once, so lazy imports do not count), under an address-space limit
and a timeout, and returns per case: the exit status, whether the child raised past the
entry point (a traceback), was killed (a hang or a crash), its peak memory growth, and the
first line of its error output.
"""

from __future__ import annotations

import ctypes
import json
import os
import random
import resource
import shutil
import signal
import struct
import subprocess
import sys
import tempfile
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

RATE_HZ = 10_000.0
SEED_SECONDS = 0.4
MAPPING = [
    '--force',
    'force',
    '--force-unit',
    'N',
    '--velocity',
    'velocity',
    '--velocity-unit',
    'm/s',
    '--sample-rate-hz',
    '10000',
]
TDMS_MAPPING = [
    arg.replace('force', 'g/force').replace('velocity', 'g/velocity') if '-' not in arg else arg
    for arg in MAPPING
]
# What each seed is read by: the command line after `fmm` ({path}: the file or bag, {out}: a
# fresh output path).
TARGETS = {
    'impact_csv': ['analyze', '{path}', '--window-s', '0.3'],
    'lab_csv': ['import', '{path}', '-o', '{out}', *MAPPING, '-q'],
    'npz': ['import', '{path}', '-o', '{out}', *MAPPING, '-q'],
    'mat_v5': ['import', '{path}', '-o', '{out}', *MAPPING, '-q'],
    'mat_v73': ['import', '{path}', '-o', '{out}', *MAPPING, '-q'],
    'tdms': ['import', '{path}', '-o', '{out}', *TDMS_MAPPING, '-q'],
    'mcap': ['analyze', '{path}', '--window-s', '0.3'],
    'mcap_info': ['bag-info', '{path}', '-q'],
    'sqlite3': ['analyze', '{path}', '--window-s', '0.3'],
    'metadata': ['bag-info', '{path}', '-q'],
    'metadata_analyze': ['analyze', '{path}', '--window-s', '0.3'],
}
MUTATIONS = ('truncate', 'bitflip', 'zero_block', 'wrong_header', 'huge_length', 'text')
MAGICS = (b'\x89MCAP0\r\n', b'SQLite format 3\x00', b'MATLAB 5.0 MAT-file', b'TDSm', b'PK\x03\x04')
HUGE = (2**31 - 1, 2**32 - 1, 2**63 - 1)
TIMEOUT_S = 20.0
ADDRESS_LIMIT_BYTES = 1 << 30
"""The child may grow its address space by this much: enough for any honest read of the seeds
(a few MB), so only a blowup meets it."""


def seed_signals() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Time [s], force [N] and velocity [m/s] of a short record with one hit."""
    n = round(SEED_SECONDS * RATE_HZ)
    t = np.arange(n) / RATE_HZ
    rng = np.random.default_rng(1)
    force = np.where((t > 0.02) & (t < 0.023), 800.0 * np.sin(np.pi * (t - 0.02) / 0.003), 0.0)
    velocity = np.where(t > 0.023, 0.08 * np.cos(2 * np.pi * 2.2 * (t - 0.023)), 0.0)
    return t, force + rng.normal(0, 0.2, n), velocity + rng.normal(0, 1e-4, n)


def write_seeds(folder: Path) -> dict[str, Path]:
    """A valid file (or bag) for every target, in folder; what each target reads."""
    import h5py
    import scipy.io
    from nptdms import ChannelObject, TdmsWriter

    from fmm_ros.core.signal.records import write_impact_csv
    from fmm_ros.io.bags.acquisitions import Acquisition, write_acquisitions
    from fmm_ros.io.bags.writer import BagWriter

    folder.mkdir(parents=True, exist_ok=True)
    t, force, velocity = seed_signals()
    seeds = {}
    write_impact_csv(folder / 'impact.csv', force, velocity, RATE_HZ)
    seeds['impact_csv'] = folder / 'impact.csv'
    np.savetxt(
        folder / 'lab.csv',
        np.column_stack((t, force, velocity)),
        delimiter=',',
        header='time,force,velocity',
        comments='',
    )
    seeds['lab_csv'] = folder / 'lab.csv'
    np.savez(folder / 'lab.npz', force=force, velocity=velocity)
    seeds['npz'] = folder / 'lab.npz'
    scipy.io.savemat(folder / 'lab_v5.mat', {'force': force, 'velocity': velocity})
    seeds['mat_v5'] = folder / 'lab_v5.mat'
    with h5py.File(folder / 'lab_v73.mat', 'w', userblock_size=512) as hdf:
        hdf['force'] = force[None, :]
        hdf['velocity'] = velocity[None, :]
    with open(folder / 'lab_v73.mat', 'r+b') as stream:
        stream.write(b'MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: fuzz HDF5 schema 1.00 .')
    seeds['mat_v73'] = folder / 'lab_v73.mat'
    with TdmsWriter(folder / 'lab.tdms') as writer:
        writer.write_segment(
            [ChannelObject('g', 'force', force), ChannelObject('g', 'velocity', velocity)]
        )
    seeds['tdms'] = folder / 'lab.tdms'
    half = force.size // 2
    for storage in ('mcap', 'sqlite3'):
        # Two acquisitions, as `fmm import` of two files writes them (the list in metadata).
        with BagWriter(folder / f'bag_{storage}', storage=storage, time_origin_ns=10**18) as bag:
            bag.write_signals(force, velocity, RATE_HZ, batch_size=500)
            bag.write_signals(force[:half], velocity[:half], RATE_HZ, first_sample_index=force.size)
            write_acquisitions(
                bag, [Acquisition(0, force.size, 'a'), Acquisition(force.size, half, 'b')]
            )
    seeds['mcap'] = folder / 'bag_mcap'
    seeds['mcap_info'] = folder / 'bag_mcap'
    seeds['sqlite3'] = folder / 'bag_sqlite3'
    seeds['metadata'] = folder / 'bag_mcap'
    seeds['metadata_analyze'] = folder / 'bag_mcap'
    return seeds


def target_file(target: str, seed: Path) -> str:
    """The file a target's mutations change, relative to its seed (a bag: one file inside)."""
    if target.startswith('metadata'):
        return 'metadata.yaml'
    if seed.is_dir():
        return next(p.name for p in sorted(seed.iterdir()) if p.suffix in ('.mcap', '.db3'))
    return ''


# -- mutations ------------------------------------------------------------------------------


def length_fields(target: str, data: bytes) -> list[tuple[int, int]]:
    """(offset, width) of length and size fields of the format's structure that we can find."""
    fields: list[tuple[int, int]] = []
    if target.startswith('mcap'):
        pos = 8  # magic
        while pos + 9 <= len(data):
            fields.append((pos + 1, 8))
            (length,) = struct.unpack_from('<Q', data, pos + 1)
            if data[pos] == 0x06 and pos + 9 + 32 <= len(data):  # chunk: sizes inside
                fields += [(pos + 9 + 16, 8)]
            pos += 9 + length
            if length > len(data):
                break
    elif target == 'sqlite3':
        fields += [(16, 2), (28, 4), (32, 4), (36, 4), (56, 4)]
    elif target == 'mat_v5':
        pos = 128
        while pos + 8 <= len(data):
            fields.append((pos + 4, 4))
            (size,) = struct.unpack_from('<I', data, pos + 4)
            fields.append((pos + 8 + 20, 4))  # first sub-element's size (array flags)
            pos += 8 + size + (-size % 8)
    elif target == 'tdms':
        pos = 0
        while pos + 28 <= len(data) and data[pos : pos + 4] == b'TDSm':
            fields += [(pos + 12, 8), (pos + 20, 8), (pos + 28 + 4, 4)]
            (next_offset,) = struct.unpack_from('<Q', data, pos + 12)
            pos += 28 + next_offset
    elif target == 'npz':
        fields += [(18, 4), (22, 4), (26, 2), (28, 2)]
        header_at = (
            30 + struct.unpack_from('<H', data, 26)[0] + struct.unpack_from('<H', data, 28)[0]
        )
        fields += [(header_at + 8, 2)]  # the .npy header length
    return [(offset, width) for offset, width in fields if offset + width <= len(data)]


def mutate(target: str, data: bytes, kind: str, rng: random.Random) -> tuple[bytes, str]:
    """The data with one mutation of `kind`, and a description of it."""
    size = len(data)
    if kind == 'truncate':
        cut = rng.randrange(0, size)
        return data[:cut], f'truncated to {cut} of {size} bytes'
    if kind == 'bitflip':
        out = bytearray(data)
        bits = rng.randint(1, 16)
        for _ in range(bits):
            at = rng.randrange(size)
            out[at] ^= 1 << rng.randrange(8)
        return bytes(out), f'{bits} bits flipped'
    if kind == 'zero_block':
        length = rng.randint(1, min(4096, size))
        at = rng.randrange(0, size - length + 1)
        return data[:at] + bytes(length) + data[at + length :], f'{length} bytes zeroed at {at}'
    if kind == 'wrong_header':
        magic = rng.choice([*MAGICS, bytes(rng.randrange(256) for _ in range(16))])
        return magic + data[len(magic) :], f'header replaced by {magic[:8]!r}'
    if kind == 'huge_length':
        fields = length_fields(target, data)
        if fields and rng.random() < 0.8:
            offset, width = rng.choice(fields)
            where = 'length field'
        else:
            width = rng.choice((4, 8))
            offset = rng.randrange(0, max(1, size - width)) // width * width
            where = 'word'
        value = min(rng.choice(HUGE), 2 ** (8 * width) - 1)
        out = bytearray(data)
        out[offset : offset + width] = value.to_bytes(width, 'little')
        return bytes(out), f'{where} at {offset} set to {value}'
    if kind == 'text':
        lines = data.split(b'\n')
        at = rng.randrange(len(lines))
        choice = rng.randrange(3)
        if choice == 0:
            lines[at] = bytes(rng.randrange(256) for _ in range(rng.randint(1, 40)))
            what = 'junk'
        elif choice == 1:
            lines[at] = lines[at].replace(b'0', b'9' * 400, 1) + b',1e999'
            what = 'huge numbers'
        else:
            lines[at] = lines[at] + b',' * (1 << 20)
            what = 'a 1 MB line'
        return b'\n'.join(lines), f'line {at}: {what}'
    raise ValueError(f'unknown mutation {kind!r}')


@dataclass(frozen=True)
class Case:
    """One mutated input: the command to run on it and what was done."""

    name: str
    target: str
    kind: str
    description: str
    path: str
    argv: list[str]
    size_bytes: int


def make_cases(seeds: dict[str, Path], folder: Path, per_target: int, seed: int) -> list[Case]:
    """per_target mutated copies of every target's seed in folder, mutations in rotation."""
    rng = random.Random(seed)
    folder.mkdir(parents=True, exist_ok=True)
    cases = []
    for target, source in seeds.items():
        inner = target_file(target, source)
        text = target in ('impact_csv', 'lab_csv') or target.startswith('metadata')
        kinds = [k for k in MUTATIONS if k != 'text' or text]
        original = (source / inner if inner else source).read_bytes()
        for number in range(per_target):
            kind = kinds[number % len(kinds)]
            name = f'{target}_{number:04d}'
            data, description = mutate(target, original, kind, rng)
            if inner:
                path = folder / name
                shutil.copytree(source, path)
                (path / inner).write_bytes(data)
            else:
                path = folder / f'{name}{source.suffix}'
                path.write_bytes(data)
            argv = [arg.format(path=path, out=folder / f'{name}_out') for arg in TARGETS[target]]
            cases.append(Case(name, target, kind, description, str(path), argv, len(data)))
    return cases


# -- the guarded runner ---------------------------------------------------------------------


@dataclass(frozen=True)
class Outcome:
    """How one case ended."""

    name: str
    verdict: str  # 'ok', 'damage', 'error', 'traceback', 'hang', 'crash'
    exit_code: int | None
    peak_growth_bytes: int
    message: str


def _status_bytes(field: str) -> int:
    """A VmSize-style field of /proc/self/status [bytes]."""
    for line in Path('/proc/self/status').read_text().splitlines():
        if line.startswith(field + ':'):
            return int(line.split()[1]) * 1024
    raise KeyError(field)


def _child(case: dict, result_fd: int) -> None:
    """Run one case in the forked child and report it on result_fd; never returns.

    Memory is the growth of the address space (VmPeak at the end over VmSize at the start:
    what was mapped, touched or not; the worker gave its free heap back to the system before
    forking, so an allocation of any size shows). RLIMIT_AS caps it, so a blowup fails here
    instead of taking the machine. (tracemalloc would also see reuse of freed memory, but
    makes pure-Python parsers ten times slower.)
    """
    try:
        start_vm = _status_bytes('VmSize')
        resource.setrlimit(
            resource.RLIMIT_AS, (start_vm + ADDRESS_LIMIT_BYTES, resource.RLIM_INFINITY)
        )
        signal.alarm(int(TIMEOUT_S))
        sink = os.open(os.devnull, os.O_WRONLY)
        err_path = case['path'] + '.stderr'
        err = os.open(err_path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC)
        os.dup2(sink, 1)
        os.dup2(err, 2)
        from fmm_ros.cli import main

        try:
            code, raised = main(case['argv']), ''
        except SystemExit as stop:
            code, raised = stop.code if isinstance(stop.code, int) else 2, ''
        except BaseException as error:  # noqa: BLE001 - the point: anything past the entry point
            code, raised = None, f'{type(error).__name__}: {error}'[:300]
        sys.stderr.flush()
        report = {
            'code': code,
            'raised': raised,
            'stderr': Path(err_path).read_text('utf-8', 'replace'),
            'growth': _status_bytes('VmPeak') - start_vm,
        }
    except BaseException as error:  # noqa: BLE001
        report = {'code': None, 'raised': f'harness: {type(error).__name__}: {error}'}
    os.write(result_fd, json.dumps(report).encode())
    os._exit(0)


def worker() -> None:
    """Serve cases (JSON lines on stdin) by forking a child each; outcomes on stdout."""
    results = os.fdopen(os.dup(1), 'w')
    os.dup2(os.open(os.devnull, os.O_WRONLY), 1)
    warm = json.loads(sys.stdin.readline())
    from fmm_ros.cli import main

    for argv in warm:  # import and exercise every reader once, outside the measurement
        try:
            main(argv)
        except BaseException:  # noqa: BLE001, S110 - warming only
            pass
    ctypes.CDLL('libc.so.6').malloc_trim(0)  # the warm-up's freed heap back to the system
    results.write('ready\n')
    results.flush()
    for line in sys.stdin:
        case = json.loads(line)
        read_fd, write_fd = os.pipe()
        pid = os.fork()
        if pid == 0:
            os.close(read_fd)
            _child(case, write_fd)
        os.close(write_fd)
        chunks = []
        while chunk := os.read(read_fd, 1 << 16):
            chunks.append(chunk)
        os.close(read_fd)
        _, status = os.waitpid(pid, 0)
        report = json.loads(b''.join(chunks)) if chunks else None
        results.write(json.dumps(_outcome(case, status, report)) + '\n')
        results.flush()


def _outcome(case: dict, status: int, report: dict | None) -> dict:
    """The verdict of one child's end."""
    if report is None:
        signum = os.WTERMSIG(status) if os.WIFSIGNALED(status) else None
        verdict = 'hang' if signum == signal.SIGALRM else 'crash'
        message = f'killed by signal {signum}' if signum else f'exit status {status}'
        return asdict(Outcome(case['name'], verdict, None, -1, message))
    growth = report.get('growth', -1)
    if report['raised']:
        return asdict(Outcome(case['name'], 'traceback', None, growth, report['raised']))
    lines = [line for line in report['stderr'].splitlines() if line.strip()]
    error = next((line for line in lines if line.startswith('fmm ') and ': error: ' in line), '')
    code = report['code']
    if code == 0:
        verdict, message = 'ok', ''
    elif code == 2 and error:
        verdict, message = 'error', error
    elif code == 1:
        verdict, message = 'damage', lines[0] if lines else ''
    else:
        verdict, message = 'traceback', lines[-1] if lines else f'exit {code}'
    return asdict(Outcome(case['name'], verdict, code, growth, message[:300]))


def run_cases(cases: list[Case], warm: list[list[str]]) -> list[Outcome]:
    """Every case through one worker process (started here, stopped at the end)."""
    env = dict(os.environ, OPENBLAS_NUM_THREADS='1', OMP_NUM_THREADS='1', NUMBA_NUM_THREADS='1')
    env['PYTHONPATH'] = os.pathsep.join(
        [str(Path(__file__).parent), env.get('PYTHONPATH', '')]
    ).rstrip(os.pathsep)
    process = subprocess.Popen(
        [sys.executable, '-c', 'import fuzz_files; fuzz_files.worker()'],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
        env=env,
    )
    try:
        process.stdin.write(json.dumps(warm) + '\n')
        process.stdin.flush()
        if process.stdout.readline().strip() != 'ready':
            raise RuntimeError('the fuzz worker did not start')
        outcomes = []
        for case in cases:
            process.stdin.write(json.dumps(asdict(case)) + '\n')
            process.stdin.flush()
            outcomes.append(Outcome(**json.loads(process.stdout.readline())))
        return outcomes
    finally:
        process.stdin.close()
        process.wait(timeout=60)


def fuzz(
    per_target: int, seed: int, folder: Path | None = None
) -> tuple[list[Case], list[Outcome]]:
    """Seeds, per_target mutations of each, and their outcomes (in a temporary folder)."""
    with tempfile.TemporaryDirectory(dir=folder) as scratch:
        scratch = Path(scratch)
        seeds = write_seeds(scratch / 'seeds')
        warm = [
            [arg.format(path=seeds[target], out=scratch / f'warm_{target}') for arg in argv]
            for target, argv in TARGETS.items()
        ]
        cases = make_cases(seeds, scratch / 'cases', per_target, seed)
        return cases, run_cases(cases, warm)


# Address-space growth a case may show: a fixed allowance for the analysis itself and a
# multiple of the file's size. The largest seen, about 25 MB, is numpy's loadtxt indexing a
# CSV line of a million empty cells in a 1.3 MB file.
GROWTH_FLOOR_BYTES = 32 << 20
GROWTH_PER_FILE_BYTE = 32


def failures(cases: list[Case], outcomes: list[Outcome]) -> dict[str, list[tuple]]:
    """What a fuzz run must not show, each list empty when it passes: a traceback, hang or
    crash; an error that does not name its file; memory beyond the allowance above."""
    pairs = list(zip(cases, outcomes, strict=True))
    return {
        'traceback, hang or crash': [
            (case.name, case.description, outcome.verdict, outcome.message)
            for case, outcome in pairs
            if outcome.verdict not in ('ok', 'damage', 'error')
        ],
        'error not naming its file': [
            (case.name, outcome.message)
            for case, outcome in pairs
            if outcome.verdict == 'error' and Path(case.path).name not in outcome.message
        ],
        'address space beyond the allowance': [
            (case.name, case.description, outcome.peak_growth_bytes)
            for case, outcome in pairs
            if outcome.peak_growth_bytes
            > GROWTH_FLOOR_BYTES + GROWTH_PER_FILE_BYTE * case.size_bytes
        ],
    }
