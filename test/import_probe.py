"""What a fresh interpreter holds after running a snippet: the start-up tests' one probe."""

import subprocess
import sys


def modules_after(code: str) -> list[str]:
    """The name of every module a fresh interpreter has imported once it has run code."""
    script = f"{code}\nimport sys\nprint(' '.join(sorted(sys.modules)))\n"
    return subprocess.run(
        [sys.executable, '-c', script], check=True, capture_output=True, text=True
    ).stdout.split()
