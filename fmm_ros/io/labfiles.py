"""Lab measurements (CSV, NPZ, MATLAB .mat v5 and v7.3, NI TDMS) into session bags.

Nothing is guessed: which channel is force and which velocity, the unit of each, and the
sample rate come from an explicit mapping (a small YAML file or command-line flags).
Values are converted to SI (force in N, velocity in m/s) by a table of known units, or by a
stated scale for sensor units such as volts (e.g. 0.125 m/s per V). The result is the bag
the recorder would have written: both channels on one sample index, 500-sample batches.

Mapping (YAML)::

    force:    {name: Hammer, unit: lbf}            # column / variable / "group/channel"
    velocity: {name: Vibrometer, unit: V, scale: 0.125}
    sample_rate_hz: 10000    # a number, a variable holding it, or leave out and give
    time: {name: Time, unit: s}                     # a time column (checked for uniformity)
"""

import contextlib
import csv
import io
import os
import zipfile
from abc import ABC, abstractmethod
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from fmm_ros.io.bags.acquisitions import Acquisition, write_acquisitions
from fmm_ros.io.bags.writer import DEFAULT_BATCH_SIZE, BagWriter

# SI value of one file unit; lookups ignore case ("MM/S" is mm/s).
FORCE_UNITS = {'N': 1.0, 'kN': 1e3, 'mN': 1e-3, 'lbf': 4.4482216152605, 'kgf': 9.80665}
VELOCITY_UNITS = {
    'm/s': 1.0,
    'cm/s': 1e-2,
    'mm/s': 1e-3,
    'um/s': 1e-6,
    'µm/s': 1e-6,
    'in/s': 0.0254,
    'ft/s': 0.3048,
}
TIME_UNITS = {'s': 1.0, 'ms': 1e-3, 'us': 1e-6, 'µs': 1e-6}
QUANTITY_UNITS = {'force': FORCE_UNITS, 'velocity': VELOCITY_UNITS, 'time': TIME_UNITS}
SI_UNITS = {'force': 'N', 'velocity': 'm/s', 'time': 's'}

# Relative spread of time steps a time column may have and still count as uniform.
UNIFORM_TIME_TOLERANCE = 0.01

FORMATS = {
    '.csv': 'CSV',
    '.txt': 'CSV',
    '.tsv': 'CSV',
    '.dat': 'CSV',
    '.npz': 'NPZ',
    '.mat': 'MATLAB',
    '.tdms': 'TDMS',
}


@dataclass(frozen=True)
class ChannelMapping:
    """Where one quantity is in the file and how its numbers become SI.

    name: column header (or 0-based column number), variable name (dots reach into MATLAB
    structs) or TDMS "group/channel". unit: unit of the numbers in the file. scale: SI units
    per file unit, for units the table does not know (V, counts); not with a known unit.
    full_scale: sensor range in file units (0: unknown).
    """

    name: str
    unit: str | None = None
    scale: float | None = None
    full_scale: float = 0.0

    def factor(self, quantity: str, file_unit: str | None = None) -> tuple[float, str]:
        """SI units per file unit, and how that was decided (for the import report)."""
        units = QUANTITY_UNITS[quantity]
        si = SI_UNITS[quantity]
        unit = self.unit or file_unit
        known = _lookup_unit(units, unit)
        if self.scale is not None:
            if known is not None:
                raise ValueError(
                    f'{quantity} {self.name!r}: unit {unit} already fixes the scale '
                    f'({known[1]:g} {si} per {unit}); drop scale, or give the raw sensor unit '
                    f'(e.g. V) with scale in {si} per that unit'
                )
            return float(self.scale), f'× {self.scale:g} {si}/{unit or "unit"} (stated scale)'
        if known is None:
            raise ValueError(
                f'{quantity} {self.name!r}: '
                + (
                    f'unit {unit!r} is not a {quantity} unit ({", ".join(units)}); for a '
                    f'sensor unit give scale in {si} per {unit}'
                    if unit
                    else f'no unit given; give unit (one of {", ".join(units)}) or a scale in '
                    f'{si} per file unit'
                )
            )
        name, value = known
        source = '' if self.unit else ' (from the file)'
        return value, (f'[{name}]{source}' if value == 1.0 else f'[{name}]{source} × {value:g}')


def _lookup_unit(units: dict[str, float], unit: str | None) -> tuple[str, float] | None:
    """(canonical name, SI factor) of unit in units, ignoring case; None when unknown."""
    if not unit:
        return None
    for name, value in units.items():
        if name.lower() == unit.strip().lower():
            return name, value
    return None


@dataclass(frozen=True)
class ImportMapping:
    """Force and velocity channels of a lab file and its sample rate (see module doc).

    sample_rate_hz: a number, or the name of a variable holding it; None to take it from
    the time channel or, for TDMS, from the channels' wf_increment property.
    """

    force: ChannelMapping
    velocity: ChannelMapping
    sample_rate_hz: float | str | None = None
    time: ChannelMapping | None = None

    @classmethod
    def from_dict(cls, spec: dict) -> 'ImportMapping':
        """A mapping from its YAML form; unknown keys are errors, not silently ignored."""
        if not isinstance(spec, dict):
            raise ValueError(f'an import mapping is a YAML mapping, got {type(spec).__name__}')
        unknown = set(spec) - {'force', 'velocity', 'sample_rate_hz', 'time'}
        if unknown:
            raise ValueError(
                f'unknown mapping keys: {", ".join(sorted(unknown))} (known: '
                'force, velocity, sample_rate_hz, time)'
            )
        for key in ('force', 'velocity'):
            if key not in spec:
                raise ValueError(f'the mapping names no {key} channel ({key}: {{name: ...}})')
        rate = spec.get('sample_rate_hz')
        return cls(
            _channel(spec['force'], 'force'),
            _channel(spec['velocity'], 'velocity'),
            rate if isinstance(rate, str) or rate is None else float(rate),
            _channel(spec['time'], 'time') if spec.get('time') else None,
        )


def _channel(spec, key: str) -> ChannelMapping:
    """One channel entry of a mapping: {name, unit, scale, full_scale} or just a name."""
    if isinstance(spec, str | int):
        return ChannelMapping(str(spec))
    if not isinstance(spec, dict) or 'name' not in spec:
        raise ValueError(f'mapping entry {key} needs a name: {key}: {{name: ..., unit: ...}}')
    unknown = set(spec) - {'name', 'unit', 'scale', 'full_scale'}
    if unknown:
        raise ValueError(f'unknown keys in mapping entry {key}: {", ".join(sorted(unknown))}')
    scale = spec.get('scale')
    return ChannelMapping(
        str(spec['name']),
        spec.get('unit'),
        None if scale is None else float(scale),
        float(spec.get('full_scale', 0.0)),
    )


def load_mapping(path: str | Path) -> dict:
    """The raw YAML of a mapping file (merged with flags before ImportMapping.from_dict)."""
    with open(path, encoding='utf-8') as stream:
        spec = yaml.safe_load(stream)
    return spec or {}


# -- file readers: names() and array(name), plus what the format knows about a channel ----------


class LabFile(ABC):
    """One lab file opened for reading its channels by name."""

    format = ''

    def __init__(self, path: Path) -> None:
        self.path = path

    @abstractmethod
    def names(self) -> list[str]:
        """Every channel or variable name this file holds."""

    @abstractmethod
    def array(self, name: str) -> np.ndarray:
        """The values of one channel or variable, as stored."""

    def channel_unit(self, name: str) -> str | None:
        """The unit the file itself states for a channel (TDMS only)."""
        return None

    def channel_increment_s(self, name: str) -> float | None:
        """The sample interval the file itself states for a channel (TDMS only)."""
        return None

    def start_time_ns(self) -> int | None:
        """Acquisition start the file states (TDMS only)."""
        return None

    def _missing(self, name: str) -> ValueError:
        return ValueError(
            f'{self.path} ({self.format}) has no channel {name!r}; it has: '
            f'{", ".join(self.names()) or "nothing"}'
        )

    def vector(self, name: str) -> np.ndarray:
        """array(name) as a 1-D float64 array; anything else is an error naming its shape."""
        values = np.asarray(self.array(name))
        squeezed = np.squeeze(values)
        if squeezed.ndim != 1:
            raise ValueError(
                f'{self.path}: {name!r} has shape {values.shape}; a channel must '
                'be a vector (one trial per file)'
            )
        if not np.issubdtype(squeezed.dtype, np.number):
            raise ValueError(f'{self.path}: {name!r} is not numeric ({squeezed.dtype})')
        return squeezed.astype(np.float64, copy=False)

    def scalar(self, name: str) -> float:
        """A scalar variable (e.g. the sample rate)."""
        values = np.asarray(self.array(name), dtype=np.float64)
        if values.size != 1:
            raise ValueError(
                f'{self.path}: {name!r} should be one number, has shape {values.shape}'
            )
        return float(values.reshape(-1)[0])


class CsvFile(LabFile):
    """Delimited text: a header row of names (else columns are named 0, 1, ...), '#' comments."""

    format = 'CSV'

    def __init__(self, path: Path) -> None:
        super().__init__(path)
        with _reading(path, self.format), path.open(encoding='utf-8', newline='') as stream:
            lines = [line for line in stream if line.strip() and not line.startswith('#')][:2]
        if not lines:
            raise ValueError(f'{path} holds no data')
        try:
            self._delimiter = csv.Sniffer().sniff(lines[-1], delimiters=',;\t ').delimiter
        except csv.Error:
            self._delimiter = ','
        first = next(csv.reader([lines[0]], delimiter=self._delimiter, skipinitialspace=True))
        first = [cell.strip() for cell in first if self._delimiter != ' ' or cell]
        self._has_header = not all(_is_number(cell) for cell in first)
        self._names = first if self._has_header else [str(i) for i in range(len(first))]
        self._table: np.ndarray | None = None

    def names(self) -> list[str]:
        """Column names from the header row, or column numbers."""
        return list(self._names)

    def array(self, name: str) -> np.ndarray:
        """One column."""
        if name not in self._names:
            raise self._missing(name)
        if self._table is None:
            with _reading(self.path, self.format):
                self._table = self._load()
        return self._table[:, self._names.index(name)]

    def _load(self) -> np.ndarray:
        """The whole table of numbers."""
        return np.loadtxt(
            self.path,
            delimiter=None if self._delimiter == ' ' else self._delimiter,
            comments='#',
            skiprows=1 if self._has_header else 0,
            ndmin=2,
            encoding='utf-8',
        )


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


class NpzFile(LabFile):
    """numpy .npz: one array per channel."""

    format = 'NPZ'

    def __init__(self, path: Path) -> None:
        super().__init__(path)
        with _reading(path, self.format), np.load(path, allow_pickle=False) as archive:
            for name in archive.files:
                _check_npy_size(path, archive.zip, f'{name}.npy')
            self._arrays = {name: archive[name] for name in archive.files}

    def names(self) -> list[str]:
        """Array names."""
        return list(self._arrays)

    def array(self, name: str) -> np.ndarray:
        """One array."""
        if name not in self._arrays:
            raise self._missing(name)
        return self._arrays[name]


class MatFile(LabFile):
    """MATLAB .mat up to v7 (scipy.io); dotted names reach into structs (data.force)."""

    format = 'MATLAB'

    def __init__(self, path: Path) -> None:
        super().__init__(path)
        from scipy.io import loadmat

        with _reading(path, self.format), _BoundedFile(path) as stream:
            contents = loadmat(stream, squeeze_me=True, struct_as_record=False)
        self._vars = {name: value for name, value in contents.items() if not name.startswith('__')}

    def names(self) -> list[str]:
        """Variables, and fields of struct variables as struct.field."""
        names: list[str] = []

        def walk(prefix: str, value) -> None:
            fields = getattr(value, '_fieldnames', None)
            if fields:
                for name in fields:
                    walk(f'{prefix}.{name}', getattr(value, name))
            else:
                names.append(prefix)

        for name, value in self._vars.items():
            walk(name, value)
        return names

    def array(self, name: str) -> np.ndarray:
        """One variable or struct field."""
        head, *rest = name.split('.')
        if head not in self._vars:
            raise self._missing(name)
        value = self._vars[head]
        for part in rest:
            if part not in (getattr(value, '_fieldnames', None) or ()):
                raise self._missing(name)
            value = getattr(value, part)
        return value


class Mat73File(LabFile):
    """MATLAB .mat v7.3 (HDF5, h5py); dotted names reach into structs (data.force)."""

    format = 'MATLAB v7.3'

    def __init__(self, path: Path) -> None:
        super().__init__(path)
        import h5py

        self._names: list[str] = []
        # MATLAB keeps strings and cells under #refs#
        with _reading(path, self.format), h5py.File(path, 'r') as hdf:
            hdf.visititems(
                lambda key, obj: (
                    self._names.append(key.replace('/', '.'))
                    if isinstance(obj, h5py.Dataset) and not key.startswith('#')
                    else None
                )
            )

    def names(self) -> list[str]:
        """Datasets, struct fields as struct.field."""
        return list(self._names)

    def array(self, name: str) -> np.ndarray:
        """One dataset (MATLAB's column-major layout does not matter for vectors)."""
        import h5py

        if name not in self._names:
            raise self._missing(name)
        with _reading(self.path, self.format), h5py.File(self.path, 'r') as hdf:
            dataset = hdf[name.replace('.', '/')]
            _check_declared_size(self.path, name, dataset.size * dataset.dtype.itemsize)
            return dataset[()]


class TdmsFile(LabFile):
    """NI TDMS (nptdms): channels as group/channel, with unit, increment and start time."""

    format = 'TDMS'

    def __init__(self, path: Path) -> None:
        super().__init__(path)
        from nptdms import TdmsFile as NpTdmsFile

        with _reading(path, self.format):
            with _BoundedFile(path) as stream:
                for group in NpTdmsFile.read_metadata(stream).groups():
                    for channel in group.channels():
                        width = getattr(channel.data_type, 'size', None) or 1
                        _check_declared_size(path, channel.path, len(channel) * width)
            with _BoundedFile(path) as stream:
                self._file = NpTdmsFile.read(stream)
        self._channels = {
            f'{group.name}/{channel.name}': channel
            for group in self._file.groups()
            for channel in group.channels()
        }

    def names(self) -> list[str]:
        """Channels as group/channel."""
        return list(self._channels)

    def _channel(self, name: str):
        if name not in self._channels:
            raise self._missing(name)
        return self._channels[name]

    def array(self, name: str) -> np.ndarray:
        """One channel's (scaled) data."""
        return self._channel(name)[:]

    def channel_unit(self, name: str) -> str | None:
        """The channel's unit_string property."""
        return self._channel(name).properties.get('unit_string') or None

    def channel_increment_s(self, name: str) -> float | None:
        """The channel's wf_increment property [s]."""
        increment = self._channel(name).properties.get('wf_increment')
        return float(increment) if increment else None

    def start_time_ns(self) -> int | None:
        """wf_start_time of the first channel that has one."""
        for channel in self._channels.values():
            start = channel.properties.get('wf_start_time')
            if start is not None:
                return int(np.datetime64(start, 'ns').astype(np.int64))
        return None


# -- damaged files: a clear error naming the file, never a parser's traceback or a blowup ---------

DECLARED_SIZE_RATIO = 64
"""A channel may declare at most this many times its file's size in bytes: compression of
real measurements gains a few times at most, so more is a corrupt length or a zip bomb."""


@contextlib.contextmanager
def _reading(path: Path, kind: str) -> Iterator[None]:
    """Turn a parsing library's failure on a damaged file into a ValueError naming it.

    The libraries (numpy's zip reader, scipy.io, h5py, nptdms) raise whatever their code meets
    on bad bytes (OSError, KeyError, struct.error, zipfile.BadZipFile, MemoryError, ...);
    inside this block every such failure means the file is not what it claims.
    """
    try:
        yield
    except FileNotFoundError:
        raise
    except ValueError as error:  # the library's own words, with the file they are about
        if str(path) in str(error):
            raise
        raise ValueError(f'{path} ({kind}): {error}') from None
    except Exception as error:  # noqa: BLE001 - the boundary to third-party parsers of bytes
        detail = str(error) or type(error).__name__
        raise ValueError(f'{path}: not a readable {kind} file ({detail})') from None


class _BoundedFile(io.FileIO):
    """A file whose read(n) never asks for more than the bytes left in it.

    Parsers read a declared length with read(n), which allocates n bytes first: a corrupt
    length of 4 GB would reserve 4 GB for a 60 kB file.
    """

    def read(self, size: int = -1) -> bytes:
        """At most the bytes left, whatever size was asked."""
        if size is not None and size > 0:
            size = min(size, max(0, os.fstat(self.fileno()).st_size - self.tell()))
        return super().read(size)


def _check_declared_size(path: Path, name: str, declared_bytes: int) -> None:
    """ValueError when a channel declares more bytes than its file can hold."""
    limit = DECLARED_SIZE_RATIO * os.stat(path).st_size
    if declared_bytes > limit:
        raise ValueError(
            f'{path}: {name!r} declares {declared_bytes} bytes of data, more than '
            f'{DECLARED_SIZE_RATIO} times the file ({os.stat(path).st_size} bytes): '
            'a corrupt length, not a measurement'
        )


def _check_npy_size(path: Path, archive: zipfile.ZipFile, member: str) -> None:
    """Check an .npz member's declared array size (its .npy header) before numpy allocates it."""
    with archive.open(member) as stream:
        version = np.lib.format.read_magic(stream)
        header = (
            np.lib.format.read_array_header_1_0
            if version == (1, 0)
            else np.lib.format.read_array_header_2_0
        )
        shape, _, dtype = header(stream)
    count = int(np.prod(shape, dtype=object)) if shape else 1
    _check_declared_size(path, member, count * dtype.itemsize)


def open_lab_file(path: str | Path) -> LabFile:
    """The reader for a lab file, chosen by its extension."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f'{path} does not exist')
    kind = FORMATS.get(path.suffix.lower())
    if kind is None:
        raise ValueError(
            f'{path}: unknown format {path.suffix!r}; supported: {", ".join(sorted(FORMATS))}'
        )
    if kind == 'CSV':
        return CsvFile(path)
    if kind == 'NPZ':
        return NpzFile(path)
    if kind == 'TDMS':
        return TdmsFile(path)
    import h5py

    return Mat73File(path) if h5py.is_hdf5(path) else MatFile(path)


# -- conversion -----------------------------------------------------------------------------------


@dataclass
class LabRecording:
    """Force [N] and velocity [m/s] of one lab file on one sample clock, and how it was mapped."""

    force_n: np.ndarray
    velocity_m_s: np.ndarray
    sample_rate_hz: float
    full_scale_force_n: float
    full_scale_velocity_m_s: float
    start_time_ns: int | None
    source: Path
    report: list[str] = field(default_factory=list)

    @property
    def duration_s(self) -> float:
        """Length of the record [s]."""
        return len(self.force_n) / self.sample_rate_hz


def read_lab_file(path: str | Path, mapping: ImportMapping) -> LabRecording:
    """Force and velocity of one lab file in SI, with the sample rate the mapping says."""
    lab = open_lab_file(path)
    channels = {}
    report = [f'{lab.path} ({lab.format})']
    for quantity, spec in (('force', mapping.force), ('velocity', mapping.velocity)):
        values = lab.vector(spec.name)
        factor, how = spec.factor(quantity, lab.channel_unit(spec.name))
        channels[quantity] = (values * factor, spec.full_scale * factor)
        report.append(
            f'  {quantity}: {spec.name!r} {how} -> {SI_UNITS[quantity]}, {len(values)} samples'
        )
        if nans := int(np.count_nonzero(np.isnan(values))):
            report.append(
                f'  warning: {quantity} has {nans} NaN samples (kept; the analyzer '
                'flags impacts over them)'
            )
    force, velocity = channels['force'][0], channels['velocity'][0]
    if len(force) != len(velocity):
        raise ValueError(
            f'{lab.path}: force {mapping.force.name!r} has {len(force)} samples '
            f'but velocity {mapping.velocity.name!r} has {len(velocity)}'
        )
    rate, how = _sample_rate(lab, mapping, len(force))
    report.append(f'  sample rate: {rate:g} Hz ({how})')
    return LabRecording(
        force,
        velocity,
        rate,
        channels['force'][1],
        channels['velocity'][1],
        lab.start_time_ns(),
        lab.path,
        report,
    )


def _sample_rate(lab: LabFile, mapping: ImportMapping, length: int) -> tuple[float, str]:
    """The sample rate [Hz] the mapping or file states, checked against a time column."""
    stated = mapping.sample_rate_hz
    rate = how = None
    if isinstance(stated, str):
        rate, how = lab.scalar(stated), f'variable {stated!r}'
    elif stated is not None:
        rate, how = float(stated), 'stated'
    if mapping.time is not None:
        time_s = lab.vector(mapping.time.name) * mapping.time.factor('time')[0]
        if len(time_s) != length:
            raise ValueError(
                f'{lab.path}: time {mapping.time.name!r} has {len(time_s)} '
                f'samples, the channels {length}'
            )
        steps = np.diff(time_s)
        step = float(np.median(steps)) if len(steps) else 0.0
        if step <= 0 or np.max(np.abs(steps - step)) > UNIFORM_TIME_TOLERANCE * step:
            raise ValueError(
                f'{lab.path}: time {mapping.time.name!r} is not uniformly '
                'increasing; the importer needs a constant sample rate'
            )
        # Over the whole span, so the rounding of each printed time stamp averages out;
        # within a millionth of a whole number of Hz (what DAQs run at), that number.
        from_time = (len(time_s) - 1) / float(time_s[-1] - time_s[0])
        if abs(from_time - round(from_time)) < 1e-6 * from_time:
            from_time = float(round(from_time))
        if rate is None:
            rate, how = from_time, f'time channel {mapping.time.name!r}'
        elif abs(from_time - rate) > UNIFORM_TIME_TOLERANCE * rate:
            raise ValueError(
                f'{lab.path}: sample rate {rate:g} Hz ({how}) disagrees with '
                f'time channel {mapping.time.name!r} ({from_time:g} Hz)'
            )
    if rate is None:
        increments = {
            lab.channel_increment_s(spec.name) for spec in (mapping.force, mapping.velocity)
        }
        if None not in increments and len(increments) == 1:
            rate, how = 1.0 / increments.pop(), 'wf_increment in the file'
        elif len(increments - {None}) > 1:
            raise ValueError(
                f'{lab.path}: force and velocity have different sample '
                f'intervals {sorted(increments - {None})} s'
            )
    if rate is None:
        raise ValueError(
            f'{lab.path}: no sample rate; state sample_rate_hz (a number or a '
            'variable name) or a time channel'
        )
    if not np.isfinite(rate) or rate <= 0:
        raise ValueError(f'{lab.path}: sample rate {rate} Hz is not a positive number')
    return rate, how


@dataclass(frozen=True)
class ImportSummary:
    """What an import wrote: the bag, its samples and rate, and the mapping report."""

    bag: Path
    samples: int
    sample_rate_hz: float
    report: list[str]

    @property
    def duration_s(self) -> float:
        """Recorded time [s]."""
        return self.samples / self.sample_rate_hz


def read_lab_files(paths: Sequence[str | Path], mapping: ImportMapping) -> list[LabRecording]:
    """Every file read with one mapping; they must share one sample rate."""
    if not paths:
        raise ValueError('no input files')
    recordings = [read_lab_file(path, mapping) for path in paths]
    rate = recordings[0].sample_rate_hz
    for recording in recordings[1:]:
        if abs(recording.sample_rate_hz - rate) > 1e-9 * rate:
            raise ValueError(
                f'{recording.source} is sampled at {recording.sample_rate_hz:g} '
                f'Hz, {recordings[0].source} at {rate:g} Hz: one bag, one rate'
            )
    return recordings


def write_recordings(
    recordings: Sequence[LabRecording],
    bag: str | Path,
    *,
    storage: str = 'mcap',
    batch_size: int = DEFAULT_BATCH_SIZE,
    start_time_ns: int | None = None,
    on_progress: Callable[[int], None] | None = None,
) -> ImportSummary:
    """One session bag of recordings, concatenated in order on one sample index.

    Each recording is its own acquisition, listed in the bag's metadata
    (`fmm_ros.io.bags.acquisitions`): replay ends impact records at its last sample instead of
    running them into the next file or padding them with missing samples.

    start_time_ns: acquisition time of the first sample; default the file's own (TDMS),
    else the first file's modification time minus the recorded duration. on_progress gets
    the samples written per batch.
    """
    rate = recordings[0].sample_rate_hz
    total = sum(len(r.force_n) for r in recordings)
    report = [line for recording in recordings for line in recording.report]
    if start_time_ns is not None:
        report.append('start time: stated')
    elif recordings[0].start_time_ns is not None:
        start_time_ns = recordings[0].start_time_ns
        report.append('start time: from the file (wf_start_time)')
    else:
        modified_ns = os.stat(recordings[0].source).st_mtime_ns
        start_time_ns = modified_ns - round(total / rate * 1e9)
        report.append(
            f'start time: {recordings[0].source.name} modified time minus the '
            'recorded duration (the file states none)'
        )
    index = 0
    acquisitions = []
    with BagWriter(bag, storage=storage, time_origin_ns=start_time_ns) as writer:
        for recording in recordings:
            acquisitions.append(Acquisition(index, len(recording.force_n), recording.source.name))
            index = writer.write_signals(
                recording.force_n,
                recording.velocity_m_s,
                rate,
                first_sample_index=index,
                batch_size=batch_size,
                full_scale_force=recording.full_scale_force_n,
                full_scale_velocity=recording.full_scale_velocity_m_s,
                on_progress=on_progress,
            )
        write_acquisitions(writer, acquisitions)
    return ImportSummary(Path(bag), total, rate, report)


def import_to_bag(
    paths: Sequence[str | Path], bag: str | Path, mapping: ImportMapping, **options
) -> ImportSummary:
    """Lab files into one session bag: read_lab_files, then write_recordings(**options)."""
    return write_recordings(read_lab_files(paths, mapping), bag, **options)
