"""A node's last resort: an exception in a callback is logged once, reported, and survived.

A bug, or data no rule foresaw, must not stop a node that serves a lab for hours (as when
one record starting before its acquisition killed the analyzer, and every later hit was lost
until a person noticed). `CallbackFaults` counts such exceptions per place and kind, logs the
first of each kind in one line (no traceback: the kind, the place, the message) and then a
running count at most every `repeat_s`, and reports ERROR on /diagnostics (part `faults`) from
the first on, so the fault is seen while the node goes on serving what it can. Every node has
one through its `Health`; `run_node` routes what escapes a callback to it, and a node that can
drop just the broken piece (the analyzer, one record) guards that piece itself (`guard`).
"""

import time
from contextlib import contextmanager

from diagnostic_msgs.msg import DiagnosticStatus
from rclpy.node import Node


class CallbackFaults:
    """Exceptions a node survived: counted per (place, kind), logged once, ERROR on /diagnostics."""

    def __init__(self, node: Node, repeat_s: float = 10.0) -> None:
        self._logger = node.get_logger()
        self._repeat_s = repeat_s
        self._counts: dict[tuple[str, str], int] = {}
        self._logged_at: dict[tuple[str, str], float] = {}
        self.last = ''
        """The latest fault, as logged."""

    @property
    def count(self) -> int:
        """Exceptions survived so far."""
        return sum(self._counts.values())

    def record(self, where: str, error: BaseException) -> None:
        """Count an exception raised at `where` (what the node was doing); log by the rule."""
        key = (where, type(error).__name__)
        count = self._counts[key] = self._counts.get(key, 0) + 1
        self.last = f'{where}: {type(error).__name__}: {error}'
        now = time.monotonic()
        if count == 1 or now - self._logged_at.get(key, 0.0) >= self._repeat_s:
            self._logged_at[key] = now
            self._logger.error(
                f'{self.last} (survived; the node goes on'
                + (f'; {count} of this kind so far)' if count > 1 else ')')
            )

    @contextmanager
    def guard(self, where: str):
        """Run a block; an exception in it is recorded and swallowed (the block is dropped)."""
        try:
            yield
        except Exception as error:  # the last resort: any fault, recorded, never raised on
            self.record(where, error)

    def status(self) -> tuple:
        """The `faults` part of /diagnostics: ERROR once any exception was survived."""
        if not self._counts:
            return DiagnosticStatus.OK, 'no exception in any callback', {}
        values = {f'{where}: {kind}': count for (where, kind), count in self._counts.items()}
        return (
            DiagnosticStatus.ERROR,
            f'{self.count} exceptions survived; last: {self.last}',
            values,
        )
