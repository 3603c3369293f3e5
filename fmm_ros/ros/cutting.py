"""Impact records cut from a node's own stream history, by the analyzer's reports.

The fitter (to fit) and the station (to draw and judge a hit) keep the recent force and
velocity streams themselves (`SampleHistory`) and cut each impact the analyzer reports on
fmm/impacts out of them by sample index, once every sample of its record has arrived. So
no record travels over the network, and a bag played into the graph works like a live
session. An impact stamped with another acquisition's clock (the source restarted in
between) is not cut from this one's samples, and impacts of another clock still waiting
when a new acquisition begins can no longer be cut: both are said in the log. An impact heard
before any sample (a station started while results were held for late joiners) waits for
its acquisition's first batch and is judged by its clock then.

Given the recorder's bags (`from_bags`), an impact whose samples the stream never held (sent
while the node was down, or no longer held) is cut from them instead: tried again every
`BAG_RETRY_S` until the bags hold its record (the recorder flushes about once a second), for
at most `BAG_WAIT_S`, and named as not held only then.
"""

import time
from pathlib import Path

from rclpy.impl.rcutils_logger import RcutilsLogger

from fmm_interfaces.msg import ImpactResult
from fmm_ros.core.signal.history import SampleHistory
from fmm_ros.core.signal.records import ImpactRecord
from fmm_ros.ros import msgs

Cut = tuple[ImpactResult, ImpactRecord]
# How often an impact waiting for the bags is tried again, and for how long [s of wall time].
BAG_RETRY_S = 1.0
BAG_WAIT_S = 30.0


class ImpactCutter:
    """Reported impacts waiting for their samples, and their records once complete."""

    def __init__(
        self, history: SampleHistory, logger: RcutilsLogger, from_bags: Path | None = None
    ) -> None:
        """Cut from history; from_bags: the recorder's bag_path, for what history missed."""
        self.history = history
        self.waiting: list[ImpactResult] = []
        self.not_held: list[int] = []
        """Ids of reported impacts whose record could not be cut (named in the log)."""
        self.from_bags = from_bags
        self.for_bags: list[tuple[ImpactResult, float, str]] = []
        """Impacts waiting for the bags: each with its deadline and why the stream missed it."""
        self._logger = logger
        self._acquisition = 0

    def batch_fed(self) -> list[Cut]:
        """After a batch went into the history: the records it completed."""
        if self.history.acquisitions != self._acquisition:
            self._acquisition = self.history.acquisitions
            kept, lost = [], []
            for msg in self.waiting:
                (kept if self._same_clock(msg) else lost).append(msg)
            if lost:
                self._logger.warning(
                    f'a new acquisition began: impacts {[m.impact_id for m in lost]} of the '
                    'previous one cannot be cut any more'
                )
            self.waiting = kept
        return self._cut()

    def impact(self, msg: ImpactResult) -> list[Cut]:
        """An impact reported: its record at once if its samples are held, else later."""
        if not self._same_clock(msg):
            self._logger.warning(
                f'impact {msg.impact_id} belongs to another acquisition than the samples '
                'held (its clock differs): not held'
            )
            return []
        self.waiting.append(msg)
        return self._cut()

    def _same_clock(self, msg: ImpactResult) -> bool:
        """Whether the impact's clock is the held acquisition's (true while none is held)."""
        rules = self.history.stream.rules
        return rules.same_clock(self.history.origin_s, _origin_s(msg)) is not False

    def _cut(self) -> list[Cut]:
        """The records of reported impacts whose samples have all arrived."""
        cuts, queued = [], False
        for msg in list(self.waiting):
            start = msg.record_start_sample_index
            length = round(msg.record_duration_s * msg.sample_rate_hz)
            if not self.history.covers(start, start + length):
                continue
            self.waiting.remove(msg)
            try:
                record = self.history.record(
                    start,
                    length,
                    trigger_sample_index=msg.trigger_sample_index,
                    source=f'impact {msg.impact_id}',
                )
            except ValueError as error:
                if self.from_bags is not None:
                    self.for_bags.append((msg, time.monotonic() + BAG_WAIT_S, str(error)))
                    queued = True
                else:
                    self._not_held(msg, str(error))
                continue
            cuts.append((msg, record))
        # A record the stream missed goes to the bags at once (one read for all of them), later
        # every BAG_RETRY_S from the node's timer: never on every batch.
        return cuts + self.cut_from_bags() if queued else cuts

    def cut_from_bags(self) -> list[Cut]:
        """The records of impacts waiting for the bags that the bags now hold."""
        if not self.for_bags:
            return []
        # Imported here: rosbags costs a node's start-up nothing unless a hit is missed.
        from fmm_ros.io.bags.backfill import RecordSpan, bag_family, records_from_bags

        paths = bag_family(self.from_bags)
        spans = [
            RecordSpan(
                msg.record_start_sample_index,
                round(msg.record_duration_s * msg.sample_rate_hz),
                _origin_s(msg),
                msg.trigger_sample_index,
                f'impact {msg.impact_id}',
            )
            for msg, _, _ in self.for_bags
        ]
        found = records_from_bags(paths, spans, self.history.stream.rules)
        cuts, still = [], []
        for k, (msg, deadline, why) in enumerate(self.for_bags):
            if k in found:
                self._logger.info(f"impact {msg.impact_id} cut from the recorder's bag ({why})")
                cuts.append((msg, found[k]))
            elif time.monotonic() > deadline:
                self._not_held(
                    msg, f'{why}; nor is it in {", ".join(map(str, paths)) or self.from_bags}'
                )
            else:
                still.append((msg, deadline, why))
        self.for_bags = still
        return cuts

    def _not_held(self, msg: ImpactResult, why: str) -> None:
        self._logger.warning(f'impact {msg.impact_id} cannot be held: {why}')
        self.not_held.append(msg.impact_id)


def _origin_s(msg: ImpactResult) -> float | None:
    """When sample 0 of the impact's acquisition was taken by its clock [s] (None: unknown)."""
    if msg.sample_rate_hz <= 0:
        return None
    return msgs.stamp_ns(msg.header.stamp) / 1e9 - msg.trigger_sample_index / msg.sample_rate_hz
