"""The ament_python package is what `ros2 run`, colcon and rosdep expect."""

import ast
import importlib.util
import os
import subprocess
import sys
from pathlib import Path

import pytest
from catkin_pkg.package import parse_package

REPO = Path(__file__).resolve().parents[1]

# Optional hardware drivers, imported only by the backend that needs them and reported as
# missing at that backend's start-up (see fmm_ros/ros/nodes/daq.py): not installed for everyone.
OPTIONAL_IMPORTS = {'nidaqmx': 'fmm_ros/ros/nodes/daq.py'}

# Top-level modules the code imports -> the package.xml key that provides them.
# An import missing here fails the test below: add it to package.xml and to this map.
ROSDEP_KEYS = {
    'ament_index_python': 'ament_index_python',
    'builtin_interfaces': 'builtin_interfaces',
    'chardet': 'python3-chardet',
    'clevercsv': 'python3-clevercsv-pip',
    'dask': 'python3-dask-pip',
    'distributed': 'python3-distributed-pip',
    'diagnostic_msgs': 'diagnostic_msgs',
    'fmm_interfaces': 'fmm_interfaces',
    'foxglove': 'python3-foxglove-sdk-pip',
    'h5py': 'python3-h5py',
    'lz4': 'python3-lz4',
    'matplotlib': 'python3-matplotlib',
    'mcap': 'python3-mcap-pip',
    'nptdms': 'python3-nptdms-pip',
    'numba': 'python3-numba',
    'numpy': 'python3-numpy',
    'PIL': 'python3-pil',
    'pyarrow': 'python3-pyarrow-pip',
    'pyuff': 'python3-pyuff-pip',
    'rcl_interfaces': 'rcl_interfaces',
    'rclpy': 'rclpy',
    'rosgraph_msgs': 'rosgraph_msgs',
    'rosbags': 'python3-rosbags-pip',
    'scipy': 'python3-scipy',
    'std_msgs': 'std_msgs',
    'tornado': 'python3-tornado',
    'tqdm': 'python3-tqdm',
    'yaml': 'python3-yaml',
    'zstandard': 'python3-zstandard',
}


def _setup_distribution():
    """setup.py read the way the venv setup reads it (launch_scripts/setup/)."""
    path = REPO / 'launch_scripts' / 'setup' / 'install_ament_layout.py'
    spec = importlib.util.spec_from_file_location('install_ament_layout', path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.read_setup(REPO)


def _third_party_imports() -> dict[str, set[str]]:
    """Top-level modules imported by fmm_ros/, each with the files importing it."""
    found: dict[str, set[str]] = {}
    for path in (REPO / 'fmm_ros').rglob('*.py'):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0:
                names = [node.module]
            else:
                continue
            for name in names:
                top = name.split('.')[0]
                if top not in sys.stdlib_module_names and top != 'fmm_ros':
                    found.setdefault(top, set()).add(str(path.relative_to(REPO)))
    return found


@pytest.mark.slow
def test_package_xml_parses_and_declares_every_runtime_import():
    package = parse_package(str(REPO / 'package.xml'))
    assert package.name == 'fmm_ros' and package.package_format == 3
    assert package.get_build_type() == 'ament_python'
    declared = {dep.name for dep in package.exec_depends}
    for module, files in sorted(_third_party_imports().items()):
        if module in OPTIONAL_IMPORTS:
            assert files == {OPTIONAL_IMPORTS[module]}, f'optional {module} imported by {files}'
            continue
        assert module in ROSDEP_KEYS, f'{module} (imported by {sorted(files)}) has no rosdep key'
        assert ROSDEP_KEYS[module] in declared, (
            f'{module} is imported by {sorted(files)} but package.xml lacks '
            f'<exec_depend>{ROSDEP_KEYS[module]}</exec_depend>'
        )


def test_pip_only_keys_are_defined_for_rosdep_and_pinned():
    """A -pip key is unknown to the ROS rosdep database: the repo must define it and pin it."""
    import yaml

    definitions = yaml.safe_load((REPO / 'rosdep' / 'fmm_ros.yaml').read_text())
    requirements = (REPO / 'launch_scripts' / 'setup' / 'requirements.txt').read_text()
    package = parse_package(str(REPO / 'package.xml'))
    depends = package.exec_depends + package.test_depends
    for key in (dep.name for dep in depends if dep.name.endswith('-pip')):
        assert key in definitions, f'{key} is not defined in rosdep/fmm_ros.yaml'
        for platform in definitions[key].values():
            for name in platform['pip']['packages']:
                assert f'\n{name}==' in requirements, f'{name} is not pinned in requirements.txt'


# Imports served by ROS (its packages, not PyPI's).
FROM_ROS = {
    'ament_index_python',
    'builtin_interfaces',
    'diagnostic_msgs',
    'fmm_interfaces',
    'rcl_interfaces',
    'rclpy',
    'rosgraph_msgs',
    'std_msgs',
}
# Keys the ROS rosdep database (rosdistro's base.yaml and python.yaml) or the ROS distribution
# itself resolves, and the workspace's own interface package; every other key of package.xml
# must be defined in rosdep/fmm_ros.yaml.
ROS_KEYS = FROM_ROS | {
    'ros2launch',
    'python3-h5py',
    'python3-matplotlib',
    'python3-numba',
    'python3-numpy',
    'python3-pil',
    'python3-pytest',
    'python3-pytest-xdist',
    'python3-scipy',
    'python3-tornado',
    'python3-tqdm',
    'python3-yaml',
}

PYPI_NAMES = {'PIL': 'pillow', 'yaml': 'pyyaml', 'foxglove': 'foxglove-sdk'}
"""PyPI names of the imports whose distribution is named otherwise."""


def test_every_package_xml_key_resolves_for_rosdep():
    """`rosdep install --from-paths .` must find every key: a ROS key or one defined here."""
    import yaml

    definitions = yaml.safe_load((REPO / 'rosdep' / 'fmm_ros.yaml').read_text())
    package = parse_package(str(REPO / 'package.xml'))
    keys = {dep.name for dep in package.exec_depends + package.test_depends}
    assert {'python3-zstandard', 'python3-lz4', 'python3-chardet'} <= keys
    assert sorted(keys - ROS_KEYS - set(definitions)) == []
    for key, rule in definitions.items():
        assert set(rule) == {'debian', 'ubuntu'}, f'{key}: define it for Debian and Ubuntu'


def test_install_requires_lists_every_import():
    """A pip install of fmm_ros brings everything the code imports (but ROS itself)."""
    required = {name.lower() for name in _setup_distribution().install_requires}
    missing = sorted(
        f'{PYPI_NAMES.get(module, module)} (imported by {sorted(files)[0]})'
        for module, files in _third_party_imports().items()
        if module not in FROM_ROS
        and module not in OPTIONAL_IMPORTS
        and PYPI_NAMES.get(module, module).lower() not in required
    )
    assert missing == []


def test_interface_package_xml_parses():
    package = parse_package(str(REPO / 'fmm_interfaces' / 'package.xml'))
    assert package.get_build_type() == 'ament_cmake'
    assert 'rosidl_interface_packages' in {group.name for group in package.member_of_groups}


def test_setup_cfg_puts_scripts_where_ros2_run_looks():
    text = (REPO / 'setup.cfg').read_text()
    assert 'script_dir=$base/lib/fmm_ros' in text
    assert 'install_scripts=$base/lib/fmm_ros' in text


def test_ros2_run_finds_every_console_script(monkeypatch):
    from ament_index_python.packages import get_package_prefix, get_package_share_directory

    if not os.environ.get('AMENT_PREFIX_PATH'):
        monkeypatch.setenv('AMENT_PREFIX_PATH', sys.prefix)  # what sourcing the venv would set
    prefix = Path(get_package_prefix('fmm_ros'))
    assert (Path(get_package_share_directory('fmm_ros')) / 'package.xml').is_file()
    scripts = _setup_distribution().entry_points['console_scripts']
    names = [entry.split('=')[0].strip() for entry in scripts]
    assert 'fmm' in names
    for name in names:
        executable = prefix / 'lib' / 'fmm_ros' / name
        assert executable.is_file(), f'{executable} missing: ros2 run fmm_ros {name} would fail'
        assert os.access(executable, os.X_OK), f'{executable} is not executable'


def _ros_free_modules() -> list[str]:
    """Every module of the core and the report, and every CLI command but the live ones."""
    # They import rclpy when run, not before.
    live = {'fmm_ros.cli.demo', 'fmm_ros.cli.record', 'fmm_ros.cli.ros'}
    modules = ['fmm_ros', 'fmm_ros.cli']
    for folder in ('core', 'report', 'cli'):
        for path in sorted((REPO / 'fmm_ros' / folder).rglob('*.py')):
            name = '.'.join(path.relative_to(REPO).with_suffix('').parts)
            modules.append(name.removesuffix('.__init__'))
    return [module for module in modules if module not in live] + sorted(live)


@pytest.mark.slow
def test_core_report_and_offline_commands_import_without_ros():
    """The core must stay ROS-free: importing any of it must not pull in rclpy."""
    code = (
        'import importlib, sys\n'
        f'for name in {_ros_free_modules()!r}:\n'
        '    importlib.import_module(name)\n'
        "bad = [m for m in ('rclpy', 'fmm_interfaces') if m in sys.modules]\n"
        'sys.exit(f"imported {bad}" if bad else 0)\n'
    )
    result = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
