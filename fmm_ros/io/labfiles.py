"""Lab measurements (delimited text, NPZ, MATLAB .mat v4-v7.3, NI TDMS): channels by name, in SI.

Which channel is force and which velocity, the unit of each, and the sample rate come from an
explicit mapping (a small YAML file or command-line flags) or from what the file itself states,
never from a guess: a unit written in the file (a units row under a text header, `Hammer [lbf]`
in a header, a TDMS `unit_string`, the names `time_s`, `force_n`, `velocity_m_s`) names the
quantity of its channel, so a file with exactly one channel in force units and one in velocity
units needs no mapping (`mapping_for` says which it took and why). Values are converted to SI
(force in N, velocity in m/s) by a table of known units, or by a stated scale for sensor units
such as volts (e.g. 0.125 m/s per V). `fmm import` writes the result as the bag the recorder
would have written; `fmm_ros.workflows.inputs` hands it to the analysis as impact records.

The reader is chosen by the file's content (`fmm_ros.io.sniff`), not its name. Text files are
read as labs write them: the encoding (a BOM, UTF-8, else chardet's guess), the delimiter
(clevercsv), a decimal comma, a header row, a units row and a preamble to skip are detected,
and each can be stated instead (`TextFormat`).

Mapping (YAML)::

    force:    {name: Hammer, unit: lbf}            # column / variable / "group/channel"
    velocity: {name: Vibrometer, unit: V, scale: 0.125}
    sample_rate_hz: 10000    # a number, a variable holding it, or leave out and give
    time: {name: Time, unit: s}                     # a time column (checked for uniformity)
"""

import contextlib
import io
import os
import re
import zipfile
from abc import ABC, abstractmethod
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from fmm_ros.constants import RESPONSE_CHANNELS
from fmm_ros.core._checks import time_base
from fmm_ros.core.signal.records import CSV_COLUMNS
from fmm_ros.core.signal.response import RESPONSE_QUANTITIES, VELOCITY
from fmm_ros.errors import BadInputError
from fmm_ros.io import sniff
from fmm_ros.io.bags.acquisitions import Acquisition, write_acquisitions
from fmm_ros.io.bags.writer import DEFAULT_BATCH_SIZE, BagWriter
from fmm_ros.io.textfiles import DETECT, TextFormat, read_table
from fmm_ros.units import QUANTITY_UNITS, SI_UNITS, lookup_unit, quantity_of_unit

CANONICAL_NAMES = {
    **dict(zip(('time', 'force', 'velocity'), CSV_COLUMNS, strict=True)),
    'acceleration': 'acceleration_m_s2',
    'displacement': 'displacement_m',
}
"""Names that state their quantity and SI unit: the per-impact CSV columns fmm writes, and
their acceleration and displacement kin."""
_CANONICAL_UNITS = {name: SI_UNITS[quantity] for quantity, name in CANONICAL_NAMES.items()}
SAMPLE_RATE_NAME = 'sample_rate_hz'
"""A scalar variable of this name (NPZ, MATLAB) is the sample rate when none is stated."""

# Relative spread of time steps a time column may have and still count as uniform. A dropped
# sample is a step twice as long; 1 % leaves room for time stamps printed with few digits at
# rates that are not a power of ten (12.8 kHz in steps of 78.125 us, printed to 1 us).
UNIFORM_TIME_TOLERANCE = 0.01


@dataclass(frozen=True)
class ChannelMapping:
    """Where one quantity is in the file and how its numbers become SI.

    name: column header (or 0-based column number), variable name (dots reach into MATLAB
    structs) or TDMS "group/channel". unit: unit of the numbers in the file. scale: SI units
    per file unit, for units the table does not know (V, counts); not with a known unit.
    full_scale: sensor range in file units (0: unknown). full_scale_si: the same in SI units
    (N, m/s), which wins over full_scale when given (the command-line flags are in SI).
    """

    name: str
    unit: str | None = None
    scale: float | None = None
    full_scale: float = 0.0
    full_scale_si: float | None = None

    def full_scale_in_si(self, factor: float) -> float:
        """The sensor range in SI units, given the channel's SI units per file unit."""
        return self.full_scale_si if self.full_scale_si is not None else self.full_scale * factor

    def factor(self, quantity: str, file_unit: str | None = None) -> tuple[float, str]:
        """SI units per file unit, and how that was decided (for the import report)."""
        units = QUANTITY_UNITS[quantity]
        si = SI_UNITS[quantity]
        unit = self.unit or file_unit
        known = lookup_unit(quantity, unit)
        if self.scale is not None:
            if known is not None:
                raise BadInputError(
                    f'{quantity} {self.name!r}: unit {unit} already fixes the scale '
                    f'({known[1]:g} {si} per {unit}); drop scale, or give the raw sensor unit '
                    f'(e.g. V) with scale in {si} per that unit'
                )
            return float(self.scale), f'× {self.scale:g} {si}/{unit or "unit"} (stated scale)'
        if known is None:
            other = quantity_of_unit(unit, quantity)
            raise BadInputError(
                f'{quantity} {self.name!r}: '
                + (
                    f'unit {unit!r} is not a {quantity} unit ({", ".join(units)}); '
                    + (
                        f'it is a unit of {other}: if the channel measures {other}, '
                        f'name it with --{other} {self.name} (or {other}: in a mapping file)'
                        if other
                        else f'for a sensor unit give scale in {si} per {unit}'
                    )
                    if unit
                    else f'no unit given; give unit (one of {", ".join(units)}) or a scale in '
                    f'{si} per file unit'
                )
            )
        name, value = known
        source = '' if self.unit else ' (from the file)'
        return value, (f'[{name}]{source}' if value == 1.0 else f'[{name}]{source} × {value:g}')


@dataclass(frozen=True)
class ImportMapping:
    """Force and response channels of a lab file and its sample rate (see module doc).

    response: the response sensor's channel, which measures response_quantity (velocity,
    acceleration or displacement; YAML: a `velocity:`, `acceleration:` or `displacement:`
    entry). sample_rate_hz: a number, or the name of a variable holding it; None to take it
    from the time channel or, for TDMS, from the channels' wf_increment property.
    """

    force: ChannelMapping
    response: ChannelMapping | None
    sample_rate_hz: float | str | None = None
    time: ChannelMapping | None = None
    response_quantity: str = VELOCITY

    @classmethod
    def from_dict(cls, spec: dict, *, force_only: bool = False) -> 'ImportMapping':
        """A mapping from its YAML form; unknown keys are errors, not silently ignored.

        force_only: the response channel is not wanted (the hammer alone), and not read.
        """
        if not isinstance(spec, dict):
            raise BadInputError(f'an import mapping is a YAML mapping, got {type(spec).__name__}')
        _check_keys(spec)
        responses = [key for key in RESPONSE_QUANTITIES if key in spec]
        if 'force' not in spec:
            raise BadInputError('the mapping names no force channel (force: {name: ...})')
        if force_only:
            responses = responses[:1]
        elif len(responses) != 1:
            raise BadInputError(
                'the mapping names '
                + (
                    f'{len(responses)} response channels ({", ".join(responses)})'
                    if responses
                    else 'no response channel'
                )
                + f'; name one of {", ".join(RESPONSE_QUANTITIES)} ({{name: ..., unit: ...}})'
            )
        rate = spec.get('sample_rate_hz')
        return cls(
            _channel(spec['force'], 'force'),
            None if force_only else _channel(spec[responses[0]], responses[0]),
            rate if isinstance(rate, str) or rate is None else float(rate),
            _channel(spec['time'], 'time') if spec.get('time') else None,
            responses[0] if responses else VELOCITY,
        )


CHANNEL_KEYS = ('name', 'unit', 'scale', 'full_scale', 'full_scale_si')
MAPPING_KEYS = ('force', *RESPONSE_QUANTITIES, 'sample_rate_hz', 'time')


def _check_keys(spec: dict) -> None:
    """BadInputError naming a key of a mapping that is no channel or setting fmm knows."""
    unknown = set(spec) - set(MAPPING_KEYS)
    if unknown:
        raise BadInputError(
            f'unknown mapping keys: {", ".join(sorted(unknown))} (a channel of an unknown '
            f'kind? known: {", ".join(MAPPING_KEYS)})'
        )


def _channel(spec, key: str) -> ChannelMapping:
    """One channel entry of a mapping: {name, unit, scale, full_scale} or just a name."""
    if isinstance(spec, str | int):
        return ChannelMapping(str(spec))
    if not isinstance(spec, dict) or 'name' not in spec:
        raise BadInputError(f'mapping entry {key} needs a name: {key}: {{name: ..., unit: ...}}')
    unknown = set(spec) - set(CHANNEL_KEYS)
    if unknown:
        raise BadInputError(f'unknown keys in mapping entry {key}: {", ".join(sorted(unknown))}')
    scale, full_scale_si = spec.get('scale'), spec.get('full_scale_si')
    return ChannelMapping(
        str(spec['name']),
        spec.get('unit'),
        None if scale is None else float(scale),
        float(spec.get('full_scale', 0.0)),
        None if full_scale_si is None else float(full_scale_si),
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
        """The unit the file itself states for a channel: here, only by a canonical name."""
        return _CANONICAL_UNITS.get(name)

    def layout(self) -> str:
        """How the file was read, when the format leaves a choice (text files)."""
        return ''

    def channel_increment_s(self, name: str) -> float | None:
        """The sample interval the file itself states for a channel (TDMS only)."""
        return None

    def start_time_ns(self) -> int | None:
        """Acquisition start the file states (TDMS only)."""
        return None

    def stamped(self, name: str) -> bool:
        """Whether a channel holds date-time stamps, read as seconds (text files only)."""
        return False

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
            raise BadInputError(
                f'{self.path}: {name!r} has shape {values.shape}; a channel must '
                'be a vector (one trial per file)'
            )
        if not np.issubdtype(squeezed.dtype, np.number):
            raise BadInputError(f'{self.path}: {name!r} is not numeric ({squeezed.dtype})')
        return squeezed.astype(np.float64, copy=False)

    def scalar(self, name: str) -> float:
        """A scalar variable (e.g. the sample rate)."""
        values = np.asarray(self.array(name), dtype=np.float64)
        if values.size != 1:
            raise BadInputError(
                f'{self.path}: {name!r} should be one number, has shape {values.shape}'
            )
        return float(values.reshape(-1)[0])


class CsvFile(LabFile):
    """Delimited text (`fmm_ros.io.textfiles`): columns by header name, else by number.

    A header cell may carry its unit (`Hammer [lbf]`, `Hammer (lbf)`), and a units row under
    the header gives each column's; a column is found by its header as written or by its
    name without the unit.
    """

    format = sniff.CSV

    def __init__(self, path: Path, text_format: TextFormat = DETECT) -> None:
        super().__init__(path)
        with _reading(path, self.format):
            self.table = read_table(path, text_format)
        self._values: np.ndarray | None = None

    def names(self) -> list[str]:
        """Column names from the header row, or column numbers."""
        return list(self.table.names)

    def _column(self, name: str) -> int:
        names = self.table.names
        if name in names:
            return names.index(name)
        bare = [index for index, header in enumerate(names) if _split_unit(header)[0] == name]
        if len(bare) != 1:
            raise self._missing(name)
        return bare[0]

    def array(self, name: str) -> np.ndarray:
        """One column."""
        column = self._column(name)
        if self._values is None:
            with _reading(self.path, self.format):
                self._values = self.table.values()
        return self._values[:, column]

    def channel_unit(self, name: str) -> str | None:
        """The column's cell in the units row, else the unit in its header, else its name's.

        A column of date-time stamps is in seconds (since its first stamp).
        """
        column = self._column(name)
        if column in self.table.stamp_columns:
            return 's'
        header = self.table.names[column]
        return self.table.units[column] or _split_unit(header)[1] or super().channel_unit(header)

    def layout(self) -> str:
        """How the text was read (delimiter, decimal, units row, encoding)."""
        return self.table.describe()

    def stamped(self, name: str) -> bool:
        """Whether the column holds date-time stamps."""
        return self._column(name) in self.table.stamp_columns


_HEADER_UNIT = re.compile(r'^(.*?)\s*[\[(]([^\[\]()]+)[\])]\s*$')


def _split_unit(header: str) -> tuple[str, str | None]:
    """'Hammer [lbf]' -> ('Hammer', 'lbf'); a header without a bracketed unit -> (header, None)."""
    match = _HEADER_UNIT.match(header)
    return (match[1], match[2].strip()) if match and match[1] else (header, None)


class NpzFile(LabFile):
    """numpy .npz: one array per channel."""

    format = sniff.NPZ

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

    format = sniff.MATLAB

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

    format = sniff.MATLAB_73

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

    format = sniff.TDMS

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
        """The channel's unit_string property (else what its name states)."""
        unit = self._channel(name).properties.get('unit_string')
        return unit or super().channel_unit(name.rsplit('/', 1)[-1])

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
        raise BadInputError(f'{path} ({kind}): {error}') from None
    except Exception as error:  # noqa: BLE001 - the boundary to third-party parsers of bytes
        detail = str(error) or type(error).__name__
        raise BadInputError(f'{path}: not a readable {kind} file ({detail})') from None


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
    size = os.stat(path).st_size
    if declared_bytes > DECLARED_SIZE_RATIO * size:
        raise BadInputError(
            f'{path}: {name!r} declares {declared_bytes} bytes of data, more than '
            f'{DECLARED_SIZE_RATIO} times the file ({size} bytes): a corrupt length, not a '
            'measurement'
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


def open_lab_file(path: str | Path, text_format: TextFormat = DETECT) -> LabFile:
    """The reader for a lab file, chosen by its content (`fmm_ros.io.sniff.file_kind`).

    text_format applies to text files (delimiter, decimal, rows to skip, encoding).
    """
    path = Path(path)
    kind = sniff.file_kind(path)
    if kind == sniff.BAG:
        raise BadInputError(f'{path} is a bag, not a lab file: give it to fmm analyze/fit/report')
    if kind == sniff.CSV:
        return CsvFile(path, text_format)
    if kind == sniff.NPZ:
        return NpzFile(path)
    if kind == sniff.TDMS:
        return TdmsFile(path)
    return Mat73File(path) if kind == sniff.MATLAB_73 else MatFile(path)


# -- conversion -----------------------------------------------------------------------------------


@dataclass
class LabRecording:
    """Force [N] and response of one lab file on one sample clock, and how it was mapped.

    response: the response sensor's samples in SI units of response_quantity (m/s for a
    velocity, m/s^2 for an acceleration, m for a displacement); full_scale_response likewise.
    """

    force_n: np.ndarray
    response: np.ndarray | None
    """None when only the force was read (`read_lab_file(force_only=True)`)."""
    sample_rate_hz: float
    full_scale_force_n: float
    full_scale_response: float
    start_time_ns: int | None
    source: Path
    report: list[str] = field(default_factory=list)
    channel_names: dict[str, str] = field(default_factory=dict)
    """The file's name of each quantity's channel ('force', and the response quantity)."""
    response_quantity: str = VELOCITY

    @property
    def duration_s(self) -> float:
        """Length of the record [s]."""
        return len(self.force_n) / self.sample_rate_hz


def read_lab_file(
    path: str | Path,
    mapping: ImportMapping | dict,
    text_format: TextFormat = DETECT,
    *,
    force_only: bool = False,
) -> LabRecording:
    """Force and response of one lab file in SI, with the sample rate the mapping says.

    mapping: an ImportMapping, or its YAML form with any part left out that the file states
    itself (`mapping_for`). force_only: read the force alone (the response is None).
    """
    lab = open_lab_file(path, text_format)
    report = [f'{lab.path} ({lab.format}{", " + lab.layout() if lab.layout() else ""})']
    if not isinstance(mapping, ImportMapping):
        mapping, notes = mapping_for(lab, mapping, force_only=force_only)
        report += [f'  {note}' for note in notes]
    channels = {}
    response = mapping.response_quantity
    wanted = [('force', mapping.force)]
    if mapping.response is not None:
        wanted.append((response, mapping.response))
    for quantity, spec in wanted:
        values = lab.vector(spec.name)
        factor, how = spec.factor(quantity, lab.channel_unit(spec.name))
        channels[quantity] = (values * factor, spec.full_scale_in_si(factor))
        report.append(
            f'  {quantity}: {spec.name!r} {how} -> {SI_UNITS[quantity]}, {len(values)} samples'
        )
        if nans := int(np.count_nonzero(np.isnan(values))):
            report.append(
                f'  warning: {quantity} has {nans} NaN samples (kept; the analyzer '
                'flags impacts over them)'
            )
    force, values = channels['force'][0], channels.get(response, (None, 0.0))[0]
    if values is not None and len(force) != len(values):
        raise BadInputError(
            f'{lab.path}: force {mapping.force.name!r} has {len(force)} samples '
            f'but {response} {mapping.response.name!r} has {len(values)}'
        )
    rate, how = _sample_rate(lab, mapping, len(force))
    report.append(f'  sample rate: {rate:g} Hz ({how})')
    return LabRecording(
        force,
        values,
        rate,
        channels['force'][1],
        channels.get(response, (None, 0.0))[1],
        lab.start_time_ns(),
        lab.path,
        report,
        {quantity: spec.name for quantity, spec in wanted},
        response,
    )


def mapping_for(
    lab: LabFile, spec: dict, *, force_only: bool = False
) -> tuple[ImportMapping, list[str]]:
    """A mapping's YAML form completed from what the file states, and what was taken so.

    A channel the spec does not name is the file's one channel whose unit (stated in the
    file, `LabFile.channel_unit`) is a unit of that quantity; several or none is an error
    that lists the channels. The response is velocity, acceleration or displacement: the one
    channel of those kinds (canonical names first, and of several canonical names the first
    of RESPONSE_QUANTITIES: `fmm simulate -o` writes velocity_m_s beside displacement_m),
    unless the spec says which kind. Without
    a stated rate, the one channel in time units becomes the time channel, else a scalar
    variable `sample_rate_hz`, else TDMS's own increments. force_only: no response is sought.
    """
    spec = dict(spec)
    _check_keys(spec)
    notes = []
    stated = {name: lab.channel_unit(name) for name in lab.names()}
    given = [quantity for quantity in RESPONSE_QUANTITIES if spec.get(quantity)]
    if len(given) > 1:
        raise BadInputError(
            f'{lab.path}: {len(given)} response channels given ({", ".join(given)}): '
            'one sensor measures the response'
        )

    def channels_of(kinds: tuple[str, ...]) -> list[tuple[str, str]]:
        """(kind, channel) of the canonical names, else of every channel in those units."""
        named = [(kind, CANONICAL_NAMES[kind]) for kind in kinds if CANONICAL_NAMES[kind] in stated]
        return named or [
            (kind, name)
            for kind in kinds
            for name, unit in stated.items()
            if lookup_unit(kind, unit)
        ]

    listing = ', '.join(f'{name} [{unit}]' if unit else name for name, unit in stated.items())
    wanted = [('force',)] if force_only else [('force',), tuple(given) or RESPONSE_QUANTITIES]
    for kinds in wanted:
        what = kinds[0] if len(kinds) == 1 else f'response ({", ".join(kinds)})'
        entry = spec.get(kinds[0]) if len(kinds) == 1 else None
        entry = {'name': entry} if isinstance(entry, str | int) else dict(entry or {})
        if 'name' in entry:
            spec[kinds[0]] = entry
            continue
        found = channels_of(kinds)
        also = ''
        if len(found) > 1 and all(name == CANONICAL_NAMES[kind] for kind, name in found):
            # fmm's own records (fmm simulate -o) hold velocity_m_s and displacement_m: the
            # first of RESPONSE_QUANTITIES (velocity: measured, neither integrated nor
            # differentiated) is the response, and the note says what else was there.
            also = f' (also {", ".join(name for _, name in found[1:])}: name one with --KIND)'
            found = found[:1]
        if len(found) != 1:
            names = ', '.join(CANONICAL_NAMES[kind] for kind in kinds)
            problem = (
                f'missing column(s) {names}, and no channel is in {" or ".join(kinds)} units'
                if not found
                else f'{len(found)} channels are in {" or ".join(kinds)} units '
                f'({", ".join(name for _, name in found)})'
            )
            flags = ' or '.join(f'--{kind} NAME' for kind in kinds)
            raise BadInputError(
                f'{lab.path} ({lab.format}): which channel is the {what}? {problem}; '
                f'name it with {flags} (and its unit, --{kinds[0]}-unit UNIT), or in a mapping '
                f'file (-m); the file has: {listing or "nothing"}'
            )
        kind, name = found[0]
        spec[kind] = {**entry, 'name': name}
        notes.append(f'{kind}: {name!r}, the one channel in {kind} units{also}')
    if spec.get('sample_rate_hz') is None and not spec.get('time'):
        times = [name for _, name in channels_of(('time',))]
        if len(times) == 1:
            spec['time'] = {'name': times[0]}
            notes.append(f'time: {times[0]!r}, the one channel in time units')
        elif SAMPLE_RATE_NAME in stated:
            spec['sample_rate_hz'] = SAMPLE_RATE_NAME
    return ImportMapping.from_dict(spec, force_only=force_only), notes


def _sample_rate(lab: LabFile, mapping: ImportMapping, length: int) -> tuple[float, str]:
    """The sample rate [Hz] the mapping or file states, checked against a time column."""
    stated = mapping.sample_rate_hz
    rate = how = None
    if isinstance(stated, str):
        rate, how = lab.scalar(stated), f'variable {stated!r}'
    elif stated is not None:
        rate, how = float(stated), 'stated'
    if mapping.time is not None:
        name = mapping.time.name
        time_s = lab.vector(name) * mapping.time.factor('time', lab.channel_unit(name))[0]
        if len(time_s) != length:
            raise BadInputError(
                f'{lab.path}: time {name!r} has {len(time_s)} samples, the channels {length}'
            )
        stamped = lab.stamped(name)
        # Stamps from a PC clock scatter: only dropped samples are refused there.
        clock = time_base(
            time_s, f'{lab.path}: time {name!r}', None if stamped else UNIFORM_TIME_TOLERANCE
        )
        from_time = clock.sample_rate_hz
        # Within a millionth of a whole number of Hz (what DAQs run at), that number.
        if not stamped and abs(from_time - round(from_time)) < 1e-6 * from_time:
            from_time = float(round(from_time))
        source = f'date-time stamps of {name!r}' if stamped else f'time channel {name!r}'
        if rate is None:
            return from_time, f'{source}, {clock.describe()}'
        if abs(from_time - rate) > UNIFORM_TIME_TOLERANCE * rate:
            raise BadInputError(
                f'{lab.path}: sample rate {rate:g} Hz ({how}) disagrees with {source} '
                f'({from_time:.6g} Hz)'
            )
        how = f'{how}; the {source} agree, {clock.describe()}'
    if rate is None:
        increments = {
            lab.channel_increment_s(spec.name)
            for spec in (mapping.force, mapping.response)
            if spec is not None
        }
        if None not in increments and len(increments) == 1:
            rate, how = 1.0 / increments.pop(), 'wf_increment in the file'
        elif len(increments - {None}) > 1:
            raise BadInputError(
                f'{lab.path}: force and {mapping.response_quantity} have different sample '
                f'intervals {sorted(increments - {None})} s'
            )
    if rate is None:
        raise BadInputError(
            f'{lab.path}: no sample rate: force and {mapping.response_quantity} have no time '
            'base (no time channel, rate variable or stated rate); state --sample-rate-hz '
            '(a number or a variable name) or --time NAME'
        )
    if not np.isfinite(rate) or rate <= 0:
        raise BadInputError(f'{lab.path}: sample rate {rate} Hz is not a positive number')
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


def read_lab_files(
    paths: Sequence[str | Path],
    mapping: ImportMapping | dict,
    text_format: TextFormat = DETECT,
) -> list[LabRecording]:
    """Every file read with one mapping (see `read_lab_file`); they must share one rate."""
    if not paths:
        raise BadInputError('no input files')
    recordings = [read_lab_file(path, mapping, text_format) for path in paths]
    rate = recordings[0].sample_rate_hz
    for recording in recordings[1:]:
        if abs(recording.sample_rate_hz - rate) > 1e-9 * rate:
            raise BadInputError(
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
    kinds = {recording.response_quantity for recording in recordings}
    if len(kinds) > 1 or any(recording.response is None for recording in recordings):
        raise BadInputError(
            'one bag, one response sensor: the files hold '
            + ', '.join(f'{r.source.name}: {r.response_quantity}' for r in recordings)
        )
    response = next(channel for channel in RESPONSE_CHANNELS if channel.quantity in kinds)
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
                recording.response,
                rate,
                first_sample_index=index,
                batch_size=batch_size,
                full_scale_force=recording.full_scale_force_n,
                full_scale_velocity=recording.full_scale_response,
                response=response,
                on_progress=on_progress,
            )
        write_acquisitions(writer, acquisitions)
    return ImportSummary(Path(bag), total, rate, report)


def import_to_bag(
    paths: Sequence[str | Path], bag: str | Path, mapping: ImportMapping | dict, **options
) -> ImportSummary:
    """Lab files into one session bag: read_lab_files, then write_recordings with options."""
    return write_recordings(read_lab_files(paths, mapping), bag, **options)
