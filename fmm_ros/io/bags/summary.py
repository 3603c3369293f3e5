"""What a bag holds: topics, counts, duration, sample channels with their rate and gaps, results.

One pass over every message (sample batches are decoded for their indices, not copied), so
it also finds what metadata cannot tell: dropped batches, a rate that changed, clipping.
It also shows what the bag says of itself: the recorder's ledger from its metadata (samples
received, missing and refused per channel, as the recorder counted them live) and the last
health status of every node recorded on /diagnostics.
"""

from collections import Counter
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from fmm_ros.core.signal.stream import ChannelLedger
from fmm_ros.io.bags.definitions import FRF_SUMMARY, IMPACT_RESULT, SAMPLE_BATCH
from fmm_ros.io.bags.reader import BagReader, channel_batch

DIAGNOSTIC_ARRAY = 'diagnostic_msgs/msg/DiagnosticArray'
_LEVELS = {0: 'OK', 1: 'WARN', 2: 'ERROR', 3: 'STALE'}


@dataclass
class ChannelSummary:
    """One SampleBatch topic: how many samples over which indices, at what rate, with gaps."""

    topic: str
    quantity: str = ''
    unit: str = ''
    sample_rate_hz: list[float] = field(default_factory=list)
    batches: int = 0
    samples: int = 0
    first_sample_index: int | None = None
    end_sample_index: int | None = None
    batch_sizes: list[int] = field(default_factory=list)
    gaps: list[tuple[int, int]] = field(default_factory=list)  # (first missing index, count)
    backward_jumps: int = 0
    clipped_samples: int = 0
    nan_samples: int = 0
    _end: int | None = field(default=None, repr=False)

    def add(self, index: int, samples: np.ndarray, rate: float, full_scale: float) -> None:
        """Account for one batch."""
        self.batches += 1
        self.samples += len(samples)
        if rate not in self.sample_rate_hz:
            self.sample_rate_hz.append(rate)
        if len(samples) not in self.batch_sizes:
            self.batch_sizes.append(len(samples))
        if self.first_sample_index is None:
            self.first_sample_index = index
        elif index > self._end:
            self.gaps.append((self._end, index - self._end))
        elif index < self._end:
            self.backward_jumps += 1
        self._end = index + len(samples)
        self.end_sample_index = max(self.end_sample_index or 0, self._end)
        if full_scale > 0:
            self.clipped_samples += int(np.count_nonzero(np.abs(samples) >= full_scale))
        self.nan_samples += int(np.count_nonzero(np.isnan(samples)))

    @property
    def missing_samples(self) -> int:
        """Samples lost in gaps."""
        return sum(count for _, count in self.gaps)


@dataclass
class BagSummary:
    """Everything `fmm bag-info` reports about one bag."""

    path: str
    storage: str
    size_bytes: int
    recovered: bool
    problems: list[str]
    topics: dict[str, dict]
    start_ns: int | None
    end_ns: int | None
    channels: dict[str, ChannelSummary]
    impacts: dict[str, object]
    frf_levels: dict[str, int]
    ros_distro: str = ''
    ledger: dict[str, dict] = field(default_factory=dict)
    """The recorder's ledger from the bag's metadata (topic -> ChannelLedger.to_dict())."""
    health: dict[str, dict] = field(default_factory=dict)
    """The last status of each node part on /diagnostics: level, message."""

    @property
    def duration_s(self) -> float:
        """Time between the first and last message [s] (log time)."""
        return 0.0 if self.start_ns is None else (self.end_ns - self.start_ns) / 1e9

    def to_dict(self) -> dict:
        """Plain data for JSON."""
        data = asdict(self)
        for channel in data['channels'].values():
            channel.pop('_end')
        data['duration_s'] = self.duration_s
        return data


def _health_of(decoded: Any) -> dict[str, dict]:
    """Each status of a decoded DiagnosticArray by name: its level's word and its message.

    The level is a byte in the message; some decoders give it as bytes, others as an int.
    """
    health = {}
    for status in decoded.status:
        level = (
            int.from_bytes(status.level, 'little')
            if isinstance(status.level, bytes)
            else int(status.level)
        )
        health[status.name] = {
            'level': _LEVELS.get(level, str(level)),
            'message': status.message,
        }
    return health


def _topic_rates(
    reader: BagReader, counts: Counter, start: int | None, end: int | None
) -> dict[str, dict]:
    """Each topic of the bag, sorted: its type, messages read and mean rate over the bag.

    The rate is over the whole bag's span (first to last message of any topic), 0 when the
    topic has a single message or the bag no span.
    """
    return {
        name: {
            'type': info.msgtype,
            'count': counts[name],
            'rate_hz': (counts[name] - 1) / ((end - start) / 1e9)
            if end and end > start and counts[name] > 1
            else 0.0,
        }
        for name, info in sorted(reader.topics.items())
    }


def summarize_bag(
    reader: BagReader, *, on_progress: Callable[[int], None] | None = None
) -> BagSummary:
    """Read the whole bag and summarize it; open reader with strict=False to list damage.

    on_progress gets 1 per message read.
    """
    path = reader.path
    size = sum(f.stat().st_size for f in path.iterdir()) if path.is_dir() else path.stat().st_size
    counts: Counter = Counter()
    start = end = None
    channels: dict[str, ChannelSummary] = {}
    impacts = {'count': 0, 'accepted': 0, 'flags': Counter(), 'levels': Counter()}
    frf_levels: dict[str, int] = {}
    decodable = {SAMPLE_BATCH, IMPACT_RESULT, FRF_SUMMARY, DIAGNOSTIC_ARRAY}
    health: dict[str, dict] = {}
    for message in reader.messages():
        counts[message.topic] += 1
        start = message.log_time_ns if start is None else min(start, message.log_time_ns)
        end = message.log_time_ns if end is None else max(end, message.log_time_ns)
        if on_progress:
            on_progress(1)
        if message.msgtype not in decodable:
            continue
        try:
            decoded = reader.decode(message)
        except ValueError as error:
            reader.problems.append(str(error))
            continue
        if message.msgtype == SAMPLE_BATCH:
            batch = channel_batch(message, decoded, reader.path)
            channel = channels.setdefault(
                message.topic, ChannelSummary(message.topic, batch.quantity, batch.unit)
            )
            channel.add(
                batch.first_sample_index, batch.samples, batch.sample_rate_hz, batch.full_scale
            )
        elif message.msgtype == DIAGNOSTIC_ARRAY:
            health.update(_health_of(decoded))
        elif message.msgtype == IMPACT_RESULT:
            impacts['count'] += 1
            impacts['accepted'] += bool(decoded.accepted)
            impacts['flags'].update(decoded.flags)
            impacts['levels'][decoded.level or '(none)'] += 1
        else:
            frf_levels[decoded.level] = int(decoded.count)
    topics = _topic_rates(reader, counts, start, end)
    impacts = {
        key: dict(value) if isinstance(value, Counter) else value for key, value in impacts.items()
    }
    return BagSummary(
        str(path),
        reader.storage,
        size,
        reader.recovered,
        list(reader.problems),
        topics,
        start,
        end,
        channels,
        impacts,
        frf_levels,
        reader.ros_distro,
        {topic: ledger.to_dict() for topic, ledger in reader.recorded_ledger.items()},
        dict(sorted(health.items())),
    )


def format_summary(summary: BagSummary) -> str:
    """The summary as the lines `fmm bag-info` prints."""
    lines = [
        f'bag:       {summary.path}',
        f'storage:   {summary.storage}, {summary.size_bytes / 1e6:.1f} MB'
        + (' (recovered by scanning: index unusable)' if summary.recovered else ''),
        f'duration:  {summary.duration_s:.3f} s',
    ]
    if summary.ros_distro:
        lines.append(f'ros:       {summary.ros_distro}')
    lines.append('topics:')
    width = max((len(t) for t in summary.topics), default=0)
    for name, info in summary.topics.items():
        lines.append(
            f'  {name:<{width}}  {info["type"]}  {info["count"]} msgs  {info["rate_hz"]:.1f} msg/s'
        )
    for channel in summary.channels.values():
        rates = ', '.join(f'{rate:g}' for rate in channel.sample_rate_hz)
        seconds = channel.samples / channel.sample_rate_hz[0] if channel.sample_rate_hz else 0
        lines.append(
            f'channel {channel.topic}: {channel.quantity} [{channel.unit}] at {rates} '
            f'Hz, {channel.samples} samples ({seconds:.3f} s) in {channel.batches} '
            f'batches of {"/".join(map(str, channel.batch_sizes))}, indices '
            f'{channel.first_sample_index}..{channel.end_sample_index}'
        )
        if channel.gaps:
            shown = ', '.join(f'{count} at {index}' for index, count in channel.gaps[:5])
            more = f' and {len(channel.gaps) - 5} more' if len(channel.gaps) > 5 else ''
            lines.append(
                f'  gaps: {len(channel.gaps)} ({channel.missing_samples} samples '
                f'missing): {shown}{more}'
            )
        else:
            lines.append('  gaps: none')
        for label, count in (
            ('index went back', channel.backward_jumps),
            ('clipped samples', channel.clipped_samples),
            ('NaN samples', channel.nan_samples),
        ):
            if count:
                lines.append(f'  {label}: {count}')
    if rates := {r for c in summary.channels.values() for r in c.sample_rate_hz}:
        if len(rates) > 1:
            lines.append(f'warning: channels disagree on the sample rate: {sorted(rates)} Hz')
    if summary.impacts['count']:
        flags = ', '.join(f'{k} {v}' for k, v in sorted(summary.impacts['flags'].items()))
        levels = ', '.join(f'{k} {v}' for k, v in sorted(summary.impacts['levels'].items()))
        lines.append(
            f'impacts:   {summary.impacts["count"]} ({summary.impacts["accepted"]} '
            f'accepted); levels: {levels}' + (f'; flags: {flags}' if flags else '')
        )
    if summary.frf_levels:
        lines.append(
            'frf:       '
            + ', '.join(
                f'{level} ({count} impacts)' for level, count in sorted(summary.frf_levels.items())
            )
        )
    if summary.ledger:
        lines.append("recorded:  the recorder's ledger (bag metadata custom_data)")
        for entry in summary.ledger.values():
            lines.append(f'  {ChannelLedger.from_dict(entry).summary()}')
    elif not summary.recovered:
        lines.append('recorded:  no ledger in the metadata (not written by the fmm recorder)')
    if summary.health:
        lines.append('health:    last status on /diagnostics')
        for name, status in summary.health.items():
            lines.append(f'  {status["level"]:<5} {name}: {status["message"]}')
    lines.extend(f'problem:   {problem}' for problem in summary.problems)
    return '\n'.join(lines)
