"""Progress on stderr for long offline work: on a terminal only, and never with --quiet.

Two displays, both tqdm: `progress_bar` counts known units (messages of a bag, samples
written), `StatusLine` shows a job that tells its steps in words, as the workflows and the
core do (`progress: Callable[[str], None]`: 'fitting mu of impact 7/30 alone'). Neither ever
writes to stdout, so `--json` output is the same with or without them.
"""

from __future__ import annotations

import sys
import threading
from typing import TYPE_CHECKING, TextIO

if TYPE_CHECKING:
    from tqdm import tqdm

# A StatusLine redraws itself this often [s], so the clock moves during a long step.
REFRESH_S = 0.5


def progress_bar(
    total: int | None, *, desc: str, unit: str, quiet: bool, stream: TextIO | None = None
) -> tqdm | HiddenBar:
    """A tqdm bar on stream (stderr); a `HiddenBar` when quiet or when stream is not a TTY."""
    stream = stream or sys.stderr
    if quiet or not stream.isatty():
        return HiddenBar(total)
    from tqdm import tqdm

    return tqdm(
        total=total,
        desc=desc,
        unit=unit,
        unit_scale=True,
        leave=False,
        file=stream,
        dynamic_ncols=True,
    )


class HiddenBar:
    """The calls a command makes on its progress bar, where none is shown.

    A disabled tqdm bar draws nothing either, but importing tqdm and making its lock
    (multiprocessing's) took 50 ms of a replay's start-up, for output never written.
    """

    def __init__(self, total: int | None) -> None:
        self.total = total

    def update(self, n: float = 1) -> None:
        """Count n more units (shown nowhere)."""

    def refresh(self) -> None:
        """Redraw (nothing to draw)."""

    def set_postfix(self, **_: object) -> None:
        """Show values after the bar (shown nowhere)."""

    def __enter__(self) -> HiddenBar:
        return self

    def __exit__(self, *_) -> None:
        pass


class StatusLine:
    """The latest step of a job and its elapsed time, on one line of stderr.

    Call it with each step's words (it is a `progress` callback); use it as a context
    manager, which clears the line at the end. Off (every call a no-op) when quiet or when
    the stream is not a terminal.
    """

    def __init__(self, *, quiet: bool, stream: TextIO | None = None) -> None:
        from tqdm import tqdm

        stream = stream or sys.stderr
        self.enabled = not quiet and stream.isatty()
        self._bar = tqdm(
            total=None,
            file=stream,
            disable=not self.enabled,
            leave=False,
            dynamic_ncols=True,
            bar_format='{desc} [{elapsed}]',
        )
        self._stop = threading.Event()
        self._ticker = threading.Thread(target=self._tick, daemon=True)

    def __call__(self, message: str) -> None:
        """Show message as the current step."""
        if self.enabled:
            self._bar.set_description_str(message)  # drawn now: steps may come faster than
            # tqdm's own redraw interval, and each says what the job is doing

    def _tick(self) -> None:
        while not self._stop.wait(REFRESH_S):
            self._bar.refresh()

    def __enter__(self) -> StatusLine:
        if self.enabled:
            self._ticker.start()
        return self

    def __exit__(self, *_) -> None:
        self._stop.set()
        if self._ticker.is_alive():
            self._ticker.join()
        self._bar.close()


def report_problems(command: str, problems: list[str]) -> int:
    """Print a bag's problems as warnings on stderr; the exit status: 1 if any, else 0."""
    for problem in problems:
        print(f'fmm {command}: warning: {problem}', file=sys.stderr)
    return 1 if problems else 0
