"""The `fmm` process keeps freed memory for reuse (a replay's page faults)."""

import fmm_ros.cli
from fmm_ros.cli import main
from fmm_ros.core import memory


def test_glibc_keeps_freed_blocks_here():
    """On Linux with glibc (this machine and CI's) both mallopt thresholds take."""
    assert memory.keep_freed_memory() is True


def test_every_fmm_command_asks_for_it(monkeypatch, capsys):
    asked = []
    monkeypatch.setattr(fmm_ros.cli, 'keep_freed_memory', lambda: asked.append(True))
    assert main(['env']) == 0
    assert asked == [True] and capsys.readouterr().out
