"""A recorded session through the signal core, exactly as the live analyzer runs it.

The analyzer node feeds each SampleBatch it receives to one `ImpactCapture` by sample index
and analyses each record the capture completes. Replay does the same with the batches of a
bag, in the order they were recorded, so offline and live find the same impacts with the
same samples, flags and FRFs; only the clock differs (here: as fast as the CPU goes). A
repeated, late or stray batch is refused and a restarted acquisition followed by the same
stream rules as live (`fmm_ros.core.signal.stream`), never a reason to refuse the bag; what
the stream refused or resynchronised on is returned as a problem, from its ledger.

A clean recording (no gap, restart or damage: `BagReader.channel_arrays`) takes a faster
road to the same records: its channels are copied straight from the file in aligned blocks
and fed to the capture, each record analysed as it completes. The stream rules take such a
recording whole either way, so the capture sees the same samples at the same indices.
"""

import dataclasses
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from fmm_ros.constants import (
    FORCE,
    FORCE_TOPIC,
    FRF_TOPIC,
    LEVEL_TOLERANCE_N,
    VELOCITY,
    VELOCITY_TOPIC,
)
from fmm_ros.core._threads import thread_imap
from fmm_ros.core.signal.analysis import (
    AnalysisConfig,
    ImpactAnalysis,
    Summary,
    analyze_impact,
    summarize,
)
from fmm_ros.core.signal.capture import DEFAULT_CAPTURE, CaptureConfig, ImpactCapture
from fmm_ros.core.signal.config import NominalLevel
from fmm_ros.core.signal.records import ImpactRecord, stable_impact_id
from fmm_ros.core.signal.response import RESPONSE_QUANTITIES, as_measured
from fmm_ros.core.signal.stream import ChannelLedger
from fmm_ros.io.bags.acquisitions import read_acquisitions
from fmm_ros.io.bags.definitions import SAMPLE_BATCH
from fmm_ros.io.bags.errors import MissingTopicError
from fmm_ros.io.bags.reader import BagReader, ChannelBatch
from fmm_ros.units import sample_si_factor

if TYPE_CHECKING:  # arrays.py: imported only where a clean recording is read whole
    from fmm_ros.io.bags.arrays import ChannelArrays

# Samples of each channel fed to the capture at once when a recording is read whole: large
# enough that the per-call cost vanishes, small enough that records complete (and their
# buffers are reused) as the blocks go by.
WHOLE_BLOCK_SAMPLES = 1 << 16


@dataclass
class Fed:
    """What a capture was fed: batches of both channels, and seconds of force signal."""

    batches: int = 0
    signal_s: float = 0.0


def capture_records(
    reader: BagReader,
    capture: CaptureConfig | ImpactCapture = DEFAULT_CAPTURE,
    *,
    force_topic: str = FORCE_TOPIC,
    velocity_topic: str = VELOCITY_TOPIC,
    reuse_buffers: bool = False,
    on_batch: Callable[[ChannelBatch], None] | None = None,
    fed: Fed | None = None,
) -> Iterator[ImpactRecord]:
    """Each impact record the live capture would complete, in the order it would.

    capture: the config of a fresh capture, or a capture to feed (its `ledger` then tells what
    the stream refused). Topics are found by their name's tail (`BagReader.find`). Records
    are tagged with their source (bag name @ trigger index). reuse_buffers: a record is valid
    only until the next one is asked for, its memory then reused (as the analyzer node does;
    a long session then runs in warm memory). on_batch sees every recorded batch as it is fed.
    A bag joined from several recordings (`fmm import`) lists them as acquisitions: the
    capture's acquisition ends at each one's last sample (`ImpactCapture.end_acquisition`),
    and at the bag's end, so no record runs into the next file or is padded with samples that
    were never taken. (A restart the bag does not state is found by the stream rules.)
    The response topic may hold an acceleration or a displacement (its batches' quantity; any
    other is read as velocity, as bags always were): each record is then made whole
    (`as_measured`); a batch of another response quantity than the first is left out and
    named in the reader's problems.
    fed, if given, counts what was fed. Without on_batch, a clean recording given a fresh
    capture is read whole and fed in blocks (see the module docstring): the same records.
    Samples are converted to SI from each batch's unit (`units.sample_si_factor`); a unit the
    table does not know raises UnitError naming it.
    """
    impacts = capture if isinstance(capture, ImpactCapture) else ImpactCapture(capture)
    feed = _BagFeed(reader, impacts, force_topic, velocity_topic, reuse_buffers)
    fed = fed if fed is not None else Fed()
    whole = (
        None
        if feed.joined or on_batch or impacts.stream.started
        else reader.channel_arrays(force_topic, velocity_topic, impacts.config.rules)
    )
    if whole is not None:
        yield from feed.whole(whole, fed)
    else:
        yield from feed.batch_by_batch(fed, on_batch)


class _BagFeed:
    """A bag's channels fed to one capture, acquisition by acquisition (`capture_records`).

    It holds what the feeding learns as it goes: the response quantity (from the first
    response batch), the index each channel reached, and the batches of the next
    acquisition read before the current one ended on every channel.
    """

    def __init__(
        self,
        reader: BagReader,
        impacts: ImpactCapture,
        force_topic: str,
        velocity_topic: str,
        reuse_buffers: bool,
    ) -> None:
        self.reader, self.impacts, self.reuse_buffers = reader, impacts, reuse_buffers
        self.quantity = {
            reader.find(force_topic, SAMPLE_BATCH): FORCE.quantity,
            reader.find(velocity_topic, SAMPLE_BATCH): VELOCITY.quantity,
        }
        try:
            acquisitions = read_acquisitions(reader.path)
        except ValueError as error:  # damaged metadata: the reader reads the bag by scanning
            reader.problems.append(f'{error}; read as one acquisition')
            acquisitions = ()
        self.joined = bool(acquisitions)
        self.boundaries = [a.first_sample_index for a in acquisitions][1:]
        self.reached = dict.fromkeys(self.quantity, 0)  # index after each channel's last sample
        self.held: list[ChannelBatch] = []  # batches of the next acquisition, read early
        self.response = ''  # the response sensor's quantity, once its first batch is read

    def tagged(self, records: list[ImpactRecord]) -> Iterator[ImpactRecord]:
        """The capture's records tagged bag@trigger and made whole from the response."""
        for record in records:
            yield as_measured(
                dataclasses.replace(
                    record, source=f'{self.reader.path.name}@{record.trigger_sample_index}'
                ),
                self.response or VELOCITY.quantity,
                self.impacts.config,
            )
            if self.reuse_buffers:
                self.impacts.recycle(record)

    def take(self, batch: ChannelBatch) -> Iterator[ImpactRecord]:
        """Feed a batch, or hold it while another channel is still in the acquisition before."""
        if self.quantity[batch.topic] == VELOCITY.quantity:
            kind = batch.quantity if batch.quantity in RESPONSE_QUANTITIES else VELOCITY.quantity
            if not self.response:
                self.response = kind
            elif kind != self.response:
                self.reader.problems.append(
                    f'{batch.topic} batch at sample {batch.first_sample_index} holds '
                    f'{batch.quantity!r}, the response before it {self.response!r}: left out'
                )
                return
        if self.boundaries and batch.first_sample_index >= self.boundaries[0]:
            self.held.append(batch)
            return
        self.reached[batch.topic] = batch.first_sample_index + len(batch.samples)
        velocity = self.quantity[batch.topic] == VELOCITY.quantity
        measured = self.response if velocity else FORCE.quantity
        factor = sample_si_factor(measured, batch.unit)  # UnitError: refused by name
        yield from self.tagged(
            self.impacts.feed(
                self.quantity[batch.topic],
                batch.first_sample_index,
                batch.samples * factor if factor != 1.0 else batch.samples,
                batch.sample_rate_hz,
                batch.full_scale * factor,
                sender=batch.frame_id,
                stamp_ns=batch.stamp_ns,
            )
        )

    def next_acquisition(self) -> Iterator[ImpactRecord]:
        """End the acquisition, then feed what was held for the next one."""
        yield from self.tagged(self.impacts.end_acquisition())
        self.boundaries.pop(0)
        early = self.held.copy()
        self.held.clear()
        for batch in early:
            yield from self.take(batch)

    def whole(self, whole: 'ChannelArrays', fed: Fed) -> Iterator[ImpactRecord]:
        """A clean recording read whole, fed to the capture in aligned blocks."""
        fed.batches, fed.signal_s = whole.batches, whole.force_signal_s
        rate, (force_scale, velocity_scale) = whole.sample_rate_hz, whole.full_scale
        for low, force, velocity in whole.blocks(WHOLE_BLOCK_SAMPLES):
            yield from self.tagged(
                self.impacts.feed_both(
                    whole.first_sample_index + low,
                    force,
                    velocity,
                    rate,
                    force_scale,
                    velocity_scale,
                    stamp_ns=whole.stamp_ns + round(low * 1e9 / rate) if whole.stamp_ns else 0,
                )
            )
        yield from self.tagged(self.impacts.flush())

    def batch_by_batch(
        self, fed: Fed, on_batch: Callable[[ChannelBatch], None] | None
    ) -> Iterator[ImpactRecord]:
        """Every recorded batch in storage order, each acquisition ended once all are past it."""
        for batch in self.reader.sample_batches(list(self.quantity)):
            yield from self.take(batch)
            fed.batches += 1
            if batch.quantity == FORCE.quantity:
                fed.signal_s += len(batch.samples) / batch.sample_rate_hz
            if on_batch:
                on_batch(batch)
            # Every channel done with this acquisition (or already into the next): end it.
            while self.held and all(
                self.reached[topic] >= self.boundaries[0]
                or any(b.topic == topic for b in self.held)
                for topic in self.quantity
            ):
                yield from self.next_acquisition()
        while self.held:
            yield from self.next_acquisition()
        impacts = self.impacts
        yield from self.tagged(impacts.end_acquisition() if self.joined else impacts.flush())


def stream_problems(ledger: dict[str, ChannelLedger]) -> list[str]:
    """What a stream refused or restarted on, one line a channel, as problems to report."""
    return [
        f'stream: {channel.summary()}'
        for channel in ledger.values()
        if channel.refused_batches or channel.refused_samples or channel.resyncs
    ]


def bag_impact_records(
    path: str | Path,
    capture: CaptureConfig = DEFAULT_CAPTURE,
    *,
    force_topic: str = FORCE_TOPIC,
    velocity_topic: str = VELOCITY_TOPIC,
) -> tuple[list[ImpactRecord], list[str]]:
    """Bag -> every impact record in its recorded streams, and the bag's problems.

    Damage does not stop it: what was readable is captured (missing samples become gaps,
    and the impacts over them are flagged), and the problems are returned for the caller
    to report. This is what offline analysis, fitting and diagnosis of a bag start from.
    """
    with BagReader(path, strict=False) as reader:
        return reader_impact_records(
            reader, capture, force_topic=force_topic, velocity_topic=velocity_topic
        )


def reader_impact_records(
    reader: BagReader,
    capture: CaptureConfig = DEFAULT_CAPTURE,
    *,
    force_topic: str = FORCE_TOPIC,
    velocity_topic: str = VELOCITY_TOPIC,
) -> tuple[list[ImpactRecord], list[str]]:
    """`bag_impact_records` of a bag already open, which the caller goes on reading."""
    impacts = ImpactCapture(capture)
    records = list(
        capture_records(reader, impacts, force_topic=force_topic, velocity_topic=velocity_topic)
    )
    return records, list(reader.problems) + stream_problems(impacts.ledger)


@dataclass(frozen=True)
class Replay:
    """What the analyzer would have published for a bag, and what it took to find out."""

    results: list[ImpactAnalysis]
    summary: Summary
    signal_s: float
    batches: int
    problems: list[str]
    ledger: dict[str, ChannelLedger]


def replay_bag(
    path: str | Path,
    capture: CaptureConfig = DEFAULT_CAPTURE,
    analysis: AnalysisConfig | None = None,
    *,
    on_result: Callable[[ImpactAnalysis], None] | None = None,
    on_progress: Callable[[int], None] | None = None,
    on_open: Callable[[int], None] | None = None,
    threads: int | None = None,
    level_tolerance_n: float | None = None,
) -> Replay:
    """Capture and analyse every impact of a bag as the live analyzer does, then summarize.

    on_result gets each ImpactAnalysis as the analyzer would publish it, in capture order
    (impact ids by `stable_impact_id`, as the analyzer gives them); on_progress gets the
    number of batches fed since its last call, on_open the number of sample batches the bag
    holds, once it is open (a progress bar's total). threads: how many records are analysed
    at once while the bag is read and captured (`thread_imap`; default: the cores there are,
    `available_threads`); each record's analysis is its own, so the results are the same
    whatever the count. level_tolerance_n: where the analysis names no levels, the levels
    the bag's analyzer recorded (`recorded_levels`) group the hits, with this tolerance
    [N]; None: its peak forces are clustered.
    """
    analysis = analysis or AnalysisConfig()
    results: list[ImpactAnalysis] = []
    fed = Fed()
    impacts = ImpactCapture(capture)
    reported = 0

    def analysed(record: ImpactRecord) -> ImpactAnalysis:
        return analyze_impact(record, capture, analysis, impact_id=stable_impact_id(record))

    with BagReader(path, strict=False) as reader:
        if on_open:
            on_open(sum(i.count for i in reader.topics.values() if i.msgtype == SAMPLE_BATCH))
        # Records in flight are analysed while later ones are captured: each keeps its own
        # buffers (no reuse_buffers), which the process's allocator hands back warm.
        records = capture_records(reader, impacts, fed=fed)
        for result in thread_imap(analysed, records, threads):
            if on_progress:
                on_progress(fed.batches - reported)
                reported = fed.batches
            results.append(result)
            if on_result:
                on_result(result)
        problems = list(reader.problems) + stream_problems(impacts.ledger)
        grouping = analysis  # the levels group the hits only once all are analysed
        if level_tolerance_n is not None and not analysis.levels:
            levels = nominal_levels(recorded_levels(reader), level_tolerance_n)
            grouping = dataclasses.replace(analysis, levels=levels)
    if on_progress:
        on_progress(fed.batches - reported)
    return Replay(
        results, summarize(results, grouping), fed.signal_s, fed.batches, problems, impacts.ledger
    )


def recorded_levels(reader: BagReader) -> dict[str, float]:
    """The nominal levels the live analyzer grouped a bag's impacts into: name -> peak [N].

    Read from the recorded FrfSummary messages (name and nominal peak force), so `fmm
    analyze`, `replay` and `report` name a bag's levels as `bag-info` and `export` show them
    (low, medium, high for the paper's). Empty when the bag recorded no levels or its
    analyzer clustered the forces (no nominal peak).
    """
    levels: dict[str, float] = {}
    if any(topic.endswith(FRF_TOPIC) for topic in reader.topics):
        for summary in reader.frf_summaries():
            if summary.nominal_peak_force_n > 0:
                levels[summary.level] = float(summary.nominal_peak_force_n)
    return levels


def nominal_levels(
    levels: dict[str, float], tolerance_n: float = LEVEL_TOLERANCE_N
) -> tuple[NominalLevel, ...]:
    """Recorded levels (`recorded_levels`, of one bag or several) in ascending force."""
    ordered = sorted(levels.items(), key=lambda item: item[1])
    return tuple(NominalLevel(name, peak, tolerance_n) for name, peak in ordered)


@dataclass(frozen=True)
class Missed:
    """What a recorder's bag holds that an analyzer which joined late never captured."""

    records: list[ImpactRecord]
    """The bag's records of other acquisitions, and of the joined one triggered before the join."""
    reported_ids: frozenset[int]
    """Ids of the impacts the bag recorded as reported (by the analyzer before this one)."""
    reached: int
    """Index after the last sample the bag holds of the joined acquisition (0: none)."""


def records_missed(
    path: Path,
    capture: CaptureConfig,
    *,
    joined_at: int,
    origin_s: float | None,
) -> Missed:
    """The records of a bag being recorded that a capture joining at sample joined_at missed.

    origin_s: when sample 0 of the joined acquisition was taken by its clock [s] (None:
    every acquisition of the bag is the joined one). Records of other acquisitions are
    missed whole; of the joined one, those triggered before joined_at (under way, or over,
    when the capture joined). A record still open at the bag's end is left out: `reached`
    says how far the bag got, so the caller can read it again once it holds more.
    """
    reached = 0

    def joined(record_origin_s: float | None) -> bool:
        return capture.rules.same_clock(record_origin_s, origin_s) is not False

    def on_batch(batch: ChannelBatch) -> None:
        nonlocal reached
        batch_origin_s = (
            batch.stamp_ns / 1e9 - batch.first_sample_index / batch.sample_rate_hz
            if batch.stamp_ns
            else None
        )
        if joined(batch_origin_s):
            reached = max(reached, batch.first_sample_index + len(batch.samples))

    with BagReader(path, strict=False) as reader:
        try:
            reported = frozenset(int(msg.impact_id) for msg in reader.impacts())
        except MissingTopicError:  # no analyzer reported anything into it
            reported = frozenset()
        records = []
        for record in capture_records(reader, capture, on_batch=on_batch):
            if not joined(record.acquisition_origin_s):
                records.append(record)
            elif (
                record.trigger_sample_index < joined_at
                and record.record_start_sample_index
                + (record.window_samples or record.force_n.size)
                <= reached
            ):
                records.append(record)
    return Missed(records, reported, reached)
