"""launch/*.launch.xml name only what the package has.

The ros2 launch system is not installed from PyPI, so the files are read as the plain XML
they are: every executable is a console script of a node in `fmm_ros.ros.nodes.NODES`, every
parameter file is one setup.py installs, every parameter set is declared in that node's PARAMS
(and takes its value), every remapping names a topic of the package, and every source's
consumers (wait_for_consumers in the params file) are started by the same file.
"""

import importlib.util
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
import yaml

from fmm_ros import constants
from fmm_ros.ros.nodes import NODES, node_module

REPO = Path(__file__).resolve().parents[1]
LAUNCH_FILES = sorted((REPO / 'launch').glob('*.launch.xml'))
SHARE = '$(find-pkg-share fmm_ros)/'
TOPICS = {
    value
    for name, value in vars(constants).items()
    if name.endswith('_TOPIC') and isinstance(value, str)
}


def installed_files() -> tuple[dict[str, Path], list[str]]:
    """share/fmm_ros/<path> -> the repo file setup.py installs there; the console scripts."""
    path = REPO / 'launch_scripts' / 'setup' / 'install_ament_layout.py'
    spec = importlib.util.spec_from_file_location('install_ament_layout', path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    dist = module.read_setup(REPO)
    prefix = 'share/fmm_ros'
    return {
        (Path(destination).relative_to(prefix) / Path(source).name).as_posix(): REPO / source
        for destination, sources in dist.data_files
        if destination.startswith(prefix)
        for source in sources
    }, dist.entry_points['console_scripts']


def resolve(text: str, arguments: dict[str, str]) -> str:
    """$(var name) by the argument's default (as ros2 launch without arguments does)."""
    return re.sub(r'\$\(var (\w+)\)', lambda match: arguments[match[1]], text)


def problems(text: str) -> list[str]:
    """What a launch file names that the package does not have, one line each."""
    files, scripts = installed_files()
    executables = {entry.split('=')[0].strip() for entry in scripts}
    root = ET.fromstring(text)
    arguments = {arg.get('name'): arg.get('default', '') for arg in root.iter('arg')}
    started = [node.get('name') for node in root.iter('node')]
    found, params_files = [], []
    for node in root.iter('node'):
        executable, name = node.get('exec'), node.get('name')
        if node.get('pkg') != 'fmm_ros' or executable not in executables:
            found.append(f'{executable}: no console script of fmm_ros')
            continue
        if executable not in NODES or name != executable:
            found.append(f'{executable}: named {name!r}, which no params file block matches')
            continue
        params = {param.name: param for param in node_module(executable).PARAMS}
        for param in node.iter('param'):
            if param.get('from') is not None:
                path = resolve(param.get('from'), arguments)
                if path not in params_files:
                    params_files.append(path)
                continue
            declared = params.get(param.get('name'))
            value = yaml.safe_load(resolve(param.get('value', ''), arguments))
            if declared is None:
                found.append(f'{executable}: no parameter {param.get("name")!r}')
            elif reason := value_problem(declared, value):
                found.append(f'{executable}: {reason}')
        for remap in node.iter('remap'):
            if remap.get('from') not in TOPICS:
                found.append(f'{executable}: remaps {remap.get("from")!r}, no fmm topic')
    for path in params_files:
        found.extend(params_file_problems(path, files, started))
    return found


def value_problem(declared, value) -> str | None:
    """Why a launch file's value does not suit a declared parameter (type, range, choices)."""
    if isinstance(declared.default, float) and type(value) is int:
        value = float(value)
    if type(value) is not type(declared.default):
        return f'{declared.name} = {value!r} is not a {type(declared.default).__name__}'
    reason = declared.problem(value)
    if reason is None and declared.limits and isinstance(value, int | float):
        low, high = declared.limits
        if not low <= value <= high:
            reason = f'{declared.name} = {value} out of range [{low}, {high}]'
    return reason


def params_file_problems(path: str, files: dict[str, Path], started: list[str]) -> list[str]:
    """A params file must be installed, and every source's consumers started with it."""
    if not path.startswith(SHARE) or path.removeprefix(SHARE) not in files:
        return [f'params file {path} is not installed by setup.py']
    blocks = yaml.safe_load(files[path.removeprefix(SHARE)].read_text())
    return [
        f'{source} waits for {consumer}, which this file does not start'
        for source in started
        for consumer in blocks.get(source, {})
        .get('ros__parameters', {})
        .get('wait_for_consumers', [])
        if consumer and consumer not in started
    ]


@pytest.mark.parametrize('path', LAUNCH_FILES, ids=lambda path: path.name)
def test_every_name_in_the_launch_file_is_the_package_s(path):
    assert problems(path.read_text()) == []


def test_the_simulated_and_the_real_rig_have_launch_files_that_are_installed():
    files, _ = installed_files()
    assert {path.name for path in LAUNCH_FILES} == {'sim_rig.launch.xml', 'real_rig.launch.xml'}
    for path in LAUNCH_FILES:
        assert files[f'launch/{path.name}'] == path
    nodes = {
        path.name: {n.get('exec') for n in ET.parse(path).iter('node')} for path in LAUNCH_FILES
    }
    assert nodes['sim_rig.launch.xml'] == {
        'hammer_sim',
        'rig_sim',
        'analyzer',
        'fitter',
        'recorder',
    }
    assert nodes['real_rig.launch.xml'] == {'daq', 'analyzer', 'fitter', 'recorder'}


def test_a_launch_file_naming_what_the_package_lacks_is_caught():
    text = f"""<launch>
      <arg name="rate" default="fast"/>
      <node pkg="fmm_ros" exec="hammer" name="hammer"/>
      <node pkg="fmm_ros" exec="hammer_sim" name="hammer_sim">
        <param from="{SHARE}config/other.yaml"/>
        <param name="rate_factr" value="2.0"/>
        <param name="rate_factor" value="$(var rate)"/>
        <param name="batch_size" value="0"/>
        <remap from="fmm/forces" to="fmm/force"/>
      </node>
      <node pkg="fmm_ros" exec="analyzer" name="analyzer">
        <param from="{SHARE}config/fmm_rig.yaml"/>
      </node>
    </launch>"""
    assert problems(text) == [
        'hammer: no console script of fmm_ros',
        "hammer_sim: no parameter 'rate_factr'",
        "hammer_sim: rate_factor = 'fast' is not a float",
        'hammer_sim: batch_size = 0 out of range [1, 1000000]',
        "hammer_sim: remaps 'fmm/forces', no fmm topic",
        f'params file {SHARE}config/other.yaml is not installed by setup.py',
        'hammer_sim waits for rig_sim, which this file does not start',
        'hammer_sim waits for fitter, which this file does not start',
        'hammer_sim waits for recorder, which this file does not start',
    ]
