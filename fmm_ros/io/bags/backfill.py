"""An impact's record cut from the recorder's bags, for a node whose own stream missed it.

A fitter killed and respawned never receives the samples sent while it was down (the sample
topics are VOLATILE), yet it hears the hits reported meanwhile (the analyzer keeps its last
100 impacts for late subscribers) and the recorder has written their samples: its writer
flushes every second, and a bag still being written is read by scanning its MCAP file. Measured
before this (`benchmarks/fault_respawn.py`, 3 runs): the respawned fitter held 5 of 6 accepted
impacts every time, the one in flight at the kill named but never fitted.

The bag's batches go through a `SampleHistory`, as the fitter's own stream does, so the record
is cut by the same stream rules (gaps NaN, a new acquisition restarts the history) and is the
record the live fitter would have cut, bit for bit.
"""

from collections.abc import Sequence
from pathlib import Path

from fmm_ros.constants import FORCE, VELOCITY, VELOCITY_TOPIC
from fmm_ros.core.signal.history import SampleHistory
from fmm_ros.core.signal.records import ImpactRecord
from fmm_ros.core.signal.stream import DEFAULT_RULES, Batch, StreamRules
from fmm_ros.io.bags.reader import BagReader
from fmm_ros.units import sample_si_factor


def bag_family(path: Path) -> list[Path]:
    """The bags of one recording: path, then the `<path>_<n>` a respawned recorder wrote."""
    found = [path] if path.exists() else []
    number = 1
    while (candidate := path.with_name(f'{path.name}_{number}')).exists():
        found.append(candidate)
        number += 1
    return found


def record_from_bags(
    paths: Sequence[Path],
    start: int,
    length: int,
    *,
    origin_s: float | None,
    trigger_sample_index: int | None = None,
    rules: StreamRules = DEFAULT_RULES,
    source: str = '',
) -> ImpactRecord | None:
    """Samples [start, start + length) of force and the response as an ImpactRecord.

    From the first bag of paths that holds all of them in an acquisition whose clock puts
    sample 0 at origin_s [s] (within rules.clock_tolerance_s; None: any acquisition). None
    when no bag does (yet: the recorder flushes about once a second). A bag that cannot be
    read is skipped: the caller names the impact it could not hold.
    """
    for path in paths:
        try:
            record = _record_from_bag(
                path,
                start,
                length,
                origin_s,
                rules,
                trigger_sample_index=trigger_sample_index,
                source=source,
            )
        except (OSError, ValueError):
            continue
        if record is not None:
            return record
    return None


def _record_from_bag(
    path: Path,
    start: int,
    length: int,
    origin_s: float | None,
    rules: StreamRules,
    **cut,
) -> ImpactRecord | None:
    stop = start + length
    with BagReader(path, strict=False) as reader:
        velocity_topic = reader.find(VELOCITY_TOPIC, 'fmm_interfaces/msg/SampleBatch')
        history: SampleHistory | None = None
        for batch in reader.sample_batches():
            if history is None:
                # The record, and as far as one channel may run ahead of the other.
                history = SampleHistory(
                    length / batch.sample_rate_hz + rules.max_skew_s + 1.0, rules
                )
            quantity = VELOCITY.quantity if batch.topic == velocity_topic else FORCE.quantity
            factor = sample_si_factor(batch.quantity, batch.unit)
            history.feed_batch(
                quantity,
                Batch.of(
                    batch.first_sample_index,
                    batch.samples * factor if factor != 1.0 else batch.samples,
                    batch.sample_rate_hz,
                    batch.full_scale * factor,
                    batch.frame_id,
                    batch.stamp_ns,
                ),
            )
            if not history.covers(start, stop):
                continue
            same_clock = rules.same_clock(history.origin_s, origin_s) is not False
            if same_clock and history.holds(start) and start >= history.first_index:
                return history.record(start, length, **cut)
    return None
