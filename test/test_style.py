"""The whole repo is ruff clean and ruff formatted (the style the brief asks for)."""

import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
RUFF = Path(sys.executable).with_name('ruff')


def test_ruff_clean():
    result = subprocess.run(
        [str(RUFF), 'check', '--no-cache', str(REPO)], capture_output=True, text=True
    )
    assert result.returncode == 0, result.stdout + result.stderr


def test_ruff_formatted():
    result = subprocess.run(
        [str(RUFF), 'format', '--check', '--no-cache', str(REPO)], capture_output=True, text=True
    )
    assert result.returncode == 0, (
        'run `.venv/bin/ruff format .` before committing:\n' + result.stdout + result.stderr
    )
