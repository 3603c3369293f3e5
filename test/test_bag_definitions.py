"""Where bag I/O finds the fmm_interfaces .msg files: checkout, ROS workspace, pip install."""

import json
import os
import shutil
import site
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from fmm_ros.io.bags import definitions
from fmm_ros.io.bags.definitions import SAMPLE_BATCH, fmm_typestore

REPO = Path(__file__).resolve().parents[1]


def test_messages_come_from_the_packages_own_msg_files():
    found = definitions.from_checkout()
    assert found is not None and 'checkout' in found.origin
    for msg in (REPO / 'fmm_interfaces' / 'msg').glob('*.msg'):
        assert found.texts[f'fmm_interfaces/msg/{msg.stem}'] == msg.read_text()
    store = fmm_typestore()
    # The type hashes equal those rosidl computed when it built fmm_interfaces (ROS graphs
    # match types by them), so the typestore describes exactly the installed messages.
    share = Path(sys.prefix) / 'share' / 'fmm_interfaces' / 'msg'
    if not share.is_dir():
        pytest.skip(f'fmm_interfaces is not built into {sys.prefix}')
    for name in found.texts:
        rosidl = json.loads((share / f'{name.rsplit("/", 1)[1]}.json').read_text())
        assert store.hash_rihs01(name) == rosidl['type_hashes'][0]['hash_string']


def test_a_ros_workspace_is_found_through_the_ament_index(tmp_path):
    prefix = tmp_path / 'install'
    (prefix / 'share' / 'ament_index' / 'resource_index' / 'packages').mkdir(parents=True)
    assert definitions.from_ament_prefixes(str(prefix)) is None  # not indexed: not found
    (prefix / 'share' / 'ament_index' / 'resource_index' / 'packages' / 'fmm_interfaces').touch()
    msg_dir = prefix / 'share' / 'fmm_interfaces' / 'msg'
    msg_dir.mkdir(parents=True)
    text = (REPO / 'fmm_interfaces' / 'msg' / 'SampleBatch.msg').read_text()
    (msg_dir / 'SampleBatch.msg').write_text(text)
    found = definitions.from_ament_prefixes(f'{tmp_path / "nothing"}:{prefix}')
    assert found.texts == {SAMPLE_BATCH: text} and str(prefix) in found.origin


@pytest.mark.slow
def test_a_plain_pip_install_carries_the_definitions_as_package_data(tmp_path):
    """Build a wheel as pip would, unpack it, and use it with no checkout and no ament."""
    source = tmp_path / 'src'
    ignore = shutil.ignore_patterns('__pycache__', '*.pyc')
    for name in ('fmm_ros', 'fmm_interfaces', 'resource'):
        shutil.copytree(REPO / name, source / name, ignore=ignore)
    for name in ('setup.py', 'setup.cfg', 'package.xml', 'MANIFEST.in'):
        shutil.copy(REPO / name, source / name)
    subprocess.run(
        [
            sys.executable,
            '-m',
            'pip',
            'wheel',
            '--no-deps',
            '--no-build-isolation',
            '--quiet',
            '-w',
            str(tmp_path / 'dist'),
            str(source),
        ],
        check=True,
        capture_output=True,
        env={**os.environ, 'PIP_NO_CACHE_DIR': '1'},
    )
    (wheel,) = (tmp_path / 'dist').glob('fmm_ros-*.whl')
    target = tmp_path / 'site'
    with zipfile.ZipFile(wheel) as archive:
        archive.extractall(target)
    shutil.rmtree(source)  # no checkout left to find the .msg files in
    # -S: no .pth files, so the editable install of this checkout stays out of the way.
    code = (
        'import sys; sys.path[:0] = sys.argv[1:]; import fmm_ros; '
        'from fmm_ros.io.bags.definitions import find_definitions, fmm_typestore; '
        'found = find_definitions(); fmm_typestore(); '
        'print(fmm_ros.__file__); print(found.origin); print(len(found.texts))'
    )
    env = {k: v for k, v in os.environ.items() if k != 'AMENT_PREFIX_PATH'}
    result = subprocess.run(
        [sys.executable, '-S', '-c', code, str(target), *site.getsitepackages()],
        capture_output=True,
        text=True,
        env=env,
        cwd=tmp_path,
    )
    assert result.returncode == 0, result.stderr
    module, origin, count = result.stdout.split('\n')[:3]
    assert module.startswith(str(target))
    messages = len(list((Path(__file__).parents[1] / 'fmm_interfaces' / 'msg').glob('*.msg')))
    assert origin.startswith('package data') and count == str(messages)
