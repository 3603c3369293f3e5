"""An impact's record cut from the recorder's bags, for a node whose own stream missed it.

A fitter killed and respawned never receives the samples sent while it was down (the sample
topics are VOLATILE), yet it hears the hits reported meanwhile (the analyzer keeps its last
100 impacts for late subscribers) and the recorder has written their samples: its writer
flushes every second, and a bag still being written is read by scanning its MCAP file. Measured
before this (`benchmarks/fault_respawn.py`, 3 runs): the respawned fitter held 5 of 6 accepted
impacts every time, the one in flight at the kill named but never fitted.

The bag's batches go through a `SampleHistory`, as the fitter's own stream does, so the record
is cut by the same stream rules (gaps NaN, a new acquisition restarts the history): the record
the live fitter would have cut from the same samples.
"""

from collections.abc import Sequence
from dataclasses import dataclass
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


@dataclass(frozen=True)
class RecordSpan:
    """A record to cut: samples [start, start + length) of the acquisition at origin_s [s]."""

    start: int
    length: int
    origin_s: float | None  # None: any acquisition
    trigger_sample_index: int | None = None
    source: str = ''


def records_from_bags(
    paths: Sequence[Path], spans: Sequence[RecordSpan], rules: StreamRules = DEFAULT_RULES
) -> dict[int, ImpactRecord]:
    """The records of spans (by their position in spans) that the bags hold whole.

    Each from the first bag of paths that holds all its samples in an acquisition whose clock
    puts sample 0 at its origin_s (`StreamRules.same_clock`); one read of each bag serves
    every span. A span no bag holds (yet: the recorder flushes about once a second) is left
    out. A bag that cannot be read is skipped: the caller names the impacts it could not hold.
    """
    found: dict[int, ImpactRecord] = {}
    for path in paths:
        wanted = {k: span for k, span in enumerate(spans) if k not in found}
        if not wanted:
            break
        try:
            found.update(_records_from_bag(path, wanted, rules))
        except (OSError, ValueError):
            continue
    return found


def _records_from_bag(
    path: Path, wanted: dict[int, RecordSpan], rules: StreamRules
) -> dict[int, ImpactRecord]:
    found: dict[int, ImpactRecord] = {}
    longest = max(span.length for span in wanted.values())
    with BagReader(path, strict=False) as reader:
        velocity_topic = reader.find(VELOCITY_TOPIC, 'fmm_interfaces/msg/SampleBatch')
        history: SampleHistory | None = None
        for batch in reader.sample_batches():
            if history is None:
                # The longest record, and as far as one channel may run ahead of the other.
                history = SampleHistory(
                    longest / batch.sample_rate_hz + rules.max_skew_s + 1.0, rules
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
            for k, span in list(wanted.items()):
                if (
                    history.covers(span.start, span.start + span.length)
                    and rules.same_clock(history.origin_s, span.origin_s) is not False
                    and history.holds(span.start)
                    and span.start >= history.first_index
                ):
                    found[k] = history.record(
                        span.start,
                        span.length,
                        trigger_sample_index=span.trigger_sample_index,
                        source=span.source,
                    )
                    del wanted[k]
            if not wanted:
                break
    return found
