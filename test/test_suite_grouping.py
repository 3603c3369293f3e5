"""The suite's own scheduling: tests sharing a module fixture stay on one xdist worker.

`make test` runs `--dist loadgroup`, and test/conftest.py groups each test that uses a fixture
shared beyond one test with its file's other such tests. With pytest 9.2 the groups were
silently lost: every module fixture was built once on each worker, and the docs site was
built twice at once into one source tree (its generated API stubs then went missing).
"""

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

GROUPED = """
import pytest

@pytest.fixture(scope='module')
def shared():
    return object()

{tests}
"""


@pytest.mark.slow
def test_tests_sharing_a_module_fixture_run_on_one_worker(tmp_path: Path):
    tests = '\n'.join(f'def test_shared_{k}(shared):\n    pass\n' for k in range(6))
    tests += '\n'.join(f'def test_alone_{k}():\n    pass\n' for k in range(6))
    (tmp_path / 'test_grouped.py').write_text(GROUPED.format(tests=tests))
    shutil.copy(Path(__file__).with_name('conftest.py'), tmp_path / 'conftest.py')
    run = subprocess.run(
        [
            sys.executable,
            '-m',
            'pytest',
            '-n',
            '2',
            '--dist',
            'loadgroup',
            '-v',
            '-p',
            'no:cacheprovider',
            str(tmp_path),
        ],
        cwd=tmp_path,
        env={**os.environ, 'PYTHONDONTWRITEBYTECODE': '1'},
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    workers = {m[2]: m[1] for m in re.finditer(r'\[(gw\d)\].*PASSED \S+::(test_\w+)', run.stdout)}
    assert len(workers) == 12, run.stdout[-3000:]
    shared = {workers[f'test_shared_{k}'] for k in range(6)}
    assert len(shared) == 1, f"the shared fixture's tests ran on {sorted(shared)}"
