"""Each node's health on /diagnostics, and its stream faults in the log once per kind.

`Health` publishes one `diagnostic_msgs/DiagnosticArray` a second (the ROS convention that
rqt_robot_monitor and Foxglove read), one `DiagnosticStatus` per part of the node, named
`<node>: <part>` with the node's full name, so two rigs in one graph stay apart.
`stream_status` turns a channel's ledger into such a status: samples received, missing and
refused, resynchronisations, the rate over the last second and how far the newest sample
lags the wall clock. `FaultLog` logs a fault kind the first time it happens, then a running
count at most every `repeat_s`: a source sending garbage for an hour writes a few lines, not
2,945. Arrays are stamped in signal time, the graph's one time base
(`fmm_ros.ros.timebase`).
"""

import time
from collections.abc import Callable
from dataclasses import dataclass, field

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.event_handler import PublisherEventCallbacks
from rclpy.node import Node

from fmm_ros.constants import DIAGNOSTICS_TOPIC
from fmm_ros.core.signal.stream import FAULTS, RESYNC_REASONS, ChannelLedger
from fmm_ros.ros import msgs
from fmm_ros.ros.faults import CallbackFaults
from fmm_ros.ros.qos import DIAGNOSTICS_QOS
from fmm_ros.ros.timebase import SignalClock

OK, WARN, ERROR = DiagnosticStatus.OK, DiagnosticStatus.WARN, DiagnosticStatus.ERROR
LEVEL_NAMES = {OK: 'OK', WARN: 'WARN', ERROR: 'ERROR', DiagnosticStatus.STALE: 'STALE'}
PERIOD_S = 1.0

Check = Callable[[], tuple[bytes, str, dict[str, object]]]
"""A part's check: (level, one-line message, key-values)."""


class Health:
    """A node's /diagnostics publisher: add parts, it publishes their checks every second."""

    def __init__(self, node: Node, period_s: float = PERIOD_S) -> None:
        self._node = node
        self._name = node.get_fully_qualified_name()
        self._checks: list[tuple[str, Check]] = []
        self._publisher = node.create_publisher(
            DiagnosticArray,
            DIAGNOSTICS_TOPIC,
            DIAGNOSTICS_QOS,
            event_callbacks=PublisherEventCallbacks(use_default_callbacks=False),
        )
        self._clock = SignalClock(node)
        node.create_timer(period_s, self.publish)
        node.health = self
        node.callback_faults = self.faults = CallbackFaults(node)
        self.add('faults', self.faults.status)

    def add(self, part: str, check: Check) -> None:
        """Report a part of the node (e.g. 'stream', 'recorder') by calling check each time."""
        self._checks.append((part, check))

    def statuses(self) -> list[DiagnosticStatus]:
        """The statuses as published now."""
        statuses = []
        for part, check in self._checks:
            level, message, values = check()
            status = DiagnosticStatus()
            status.level = level
            status.name = f'{self._name}: {part}'
            status.message = message
            status.hardware_id = self._name
            status.values = [KeyValue(key=key, value=_text(value)) for key, value in values.items()]
            statuses.append(status)
        return statuses

    def publish(self) -> None:
        """One DiagnosticArray of every part."""
        array = DiagnosticArray()
        array.header.stamp = msgs.time_msg(self._clock.now_ns())  # signal time, as all stamps
        array.status = self.statuses()
        self._publisher.publish(array)


def _text(value: object) -> str:
    if isinstance(value, float):
        return f'{value:.6g}'
    return str(value)


@dataclass
class ChannelRate:
    """Samples a second of a channel over the last period, and the newest sample's stamp."""

    received: int = 0
    at: float = field(default_factory=time.monotonic)
    rate: float = 0.0
    newest_stamp_ns: int = 0

    def update(self, ledger: ChannelLedger) -> float:
        """The rate since the previous call [samples/s]."""
        now = time.monotonic()
        if now - self.at >= 0.5:
            self.rate = (ledger.received_samples - self.received) / (now - self.at)
            self.received, self.at = ledger.received_samples, now
        return self.rate


def stream_status(
    ledgers: dict[str, ChannelLedger], rates: dict[str, ChannelRate]
) -> tuple[bytes, str, dict[str, object]]:
    """A consumer's stream part: WARN on any missing or refused sample, per channel values.

    ERROR on a unit no table knows: nothing of that channel can be used.
    """
    values: dict[str, object] = {}
    lines = []
    level = OK
    for name, ledger in ledgers.items():
        rate = rates.setdefault(name, ChannelRate())
        per_s = rate.update(ledger)
        lag_s = (time.time_ns() - rate.newest_stamp_ns) / 1e9 if rate.newest_stamp_ns else 0.0
        span = ledger.span
        values.update(
            {
                f'{name} received samples': ledger.received_samples,
                f'{name} missing samples': ledger.missing_samples,
                f'{name} refused batches': ledger.refused_batches,
                f'{name} refused samples': ledger.refused_samples,
                f'{name} resyncs': ledger.resyncs,
                f'{name} span': f'{span[0]}..{span[1]}' if span else 'none',
                f'{name} rate samples/s': per_s,
                f'{name} lag behind wall clock s': lag_s,
            }
        )
        for kind, count in sorted(ledger.faults.items()):
            values[f'{name} fault {kind}'] = count
        if ledger.faults.get('unit'):  # nothing of the channel can be used: a setup error
            level = ERROR
        elif ledger.missing_samples or ledger.refused_samples or ledger.refused_batches:
            level = max(level, WARN)
        lines.append(
            f'{name} {ledger.received_samples} received, {ledger.missing_samples} missing, '
            f'{ledger.refused_batches} refused'
        )
    return level, '; '.join(lines) or 'no channel yet', values


class FaultLog:
    """Logs stream faults once per kind, then a running count at most every repeat_s."""

    def __init__(self, node: Node, repeat_s: float = 10.0) -> None:
        self._logger = node.get_logger()
        self._repeat_s = repeat_s
        self._logged: dict[tuple[str, str], tuple[int, float]] = {}

    def check(self, ledgers: dict[str, ChannelLedger], detail: str = '') -> None:
        """Log what the ledgers counted since the last check, by the rule above."""
        now = time.monotonic()
        for name, ledger in ledgers.items():
            for kind, count in ledger.faults.items():
                last_count, last_time = self._logged.get((name, kind), (0, -1e9))
                if count == last_count:
                    continue
                first = last_count == 0
                if not first and now - last_time < self._repeat_s:
                    continue
                self._logged[(name, kind)] = (count, now)
                text = (
                    f'{name}: {FAULTS.get(kind, kind)}'
                    + (f' ({detail})' if first and detail else '')
                    + (f'; {count} so far' if count > 1 else '')
                )
                if kind in RESYNC_REASONS:
                    self._logger.warning(f'{text}: resynchronised')
                elif kind in ('gap', 'skew', 'jump'):
                    self._logger.warning(text)
                else:
                    self._logger.error(f'{text}: refused')
