"""`fmm env`: the shell lines that make this venv a ROS 2 prefix, from a plain shell.

The venv holds ROS 2 Jazzy from PyPI and fmm_ros in the ament layout colcon would make
(`share/ament_index`, `lib/fmm_ros/<node>`), but nothing sources a `setup.bash` there, so
`ament_index_python.get_package_prefix('fmm_ros')` fails for want of AMENT_PREFIX_PATH.
`eval "$(.venv/bin/fmm env)"` sets it and its friends; `launch_scripts/setup_env.sh` puts the
same lines into `.venv/bin/activate`. `fmm env --check` shows that the package and its node
executables are found.
"""

from __future__ import annotations

import argparse
import os
import re
import shlex
import sys
from pathlib import Path

PACKAGE = 'fmm_ros'
MARK = '# fmm_ros: this venv as a ROS 2 prefix (written by `fmm env`)'
_DISTRO_WHEEL = re.compile(r'^ros-([a-z]+)-rclpy$')


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add `fmm env`."""
    parser = subparsers.add_parser(
        'env',
        help='shell lines that set AMENT_PREFIX_PATH and friends for this venv',
        description='Print POSIX shell lines that make this venv a ROS 2 prefix: '
        'AMENT_PREFIX_PATH and CMAKE_PREFIX_PATH (prepended once), ROS_DISTRO, ROS_VERSION, '
        'ROS_PYTHON_VERSION, and the venv on PATH. Use: eval "$(.venv/bin/fmm env)". '
        '--check shows what get_package_prefix and the node executables resolve to.',
    )
    parser.add_argument(
        '--check',
        action='store_true',
        help='apply them in-process and show the package prefix and its node executables',
    )
    parser.set_defaults(func=run)


def ros_distro() -> str:
    """The ROS distribution of the installed rclpy wheel (its name: ros-<distro>-rclpy)."""
    import importlib.metadata  # here: 40 ms that `fmm --help` need not pay

    for distribution in importlib.metadata.distributions():
        match = _DISTRO_WHEEL.match((distribution.metadata['Name'] or '').lower())
        if match:
            return match[1]
    return os.environ.get('ROS_DISTRO', '')


def shell_lines(prefix: Path) -> list[str]:
    """The lines `fmm env` prints for a venv at prefix (idempotent when sourced again)."""
    quoted = shlex.quote(str(prefix))
    lines = [MARK]
    for name in ('AMENT_PREFIX_PATH', 'CMAKE_PREFIX_PATH'):
        lines.append(
            f'case ":${{{name}:-}}:" in *:{quoted}:*) ;; *) '
            f'export {name}={quoted}"${{{name}:+:${{{name}}}}}" ;; esac'
        )
    lines.append(
        f'case ":${{PATH}}:" in *:{shlex.quote(str(prefix / "bin"))}:*) ;; *) '
        f'export PATH={shlex.quote(str(prefix / "bin"))}":${{PATH}}" ;; esac'
    )
    distro = ros_distro()
    if distro:
        lines.append(f'export ROS_DISTRO={shlex.quote(distro)}')
    lines.append('export ROS_VERSION=2 ROS_PYTHON_VERSION=3')
    return lines


def run(args: argparse.Namespace) -> int:
    """Print the lines, or check what they resolve to."""
    prefix = Path(sys.prefix)
    if not args.check:
        print('\n'.join(shell_lines(prefix)))
        return 0
    from ament_index_python.packages import PackageNotFoundError, get_package_prefix

    paths = os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep)
    if str(prefix) not in paths:
        os.environ['AMENT_PREFIX_PATH'] = os.pathsep.join(filter(None, [str(prefix), *paths]))
    try:
        found = Path(get_package_prefix(PACKAGE))
    except PackageNotFoundError:
        print(f'{PACKAGE} is not in the ament index of {prefix}: run launch_scripts/setup_env.sh')
        return 1
    nodes = sorted(path.name for path in (found / 'lib' / PACKAGE).iterdir() if path.is_file())
    print(f"get_package_prefix('{PACKAGE}') = {found}")
    print(f'ROS_DISTRO = {ros_distro() or "unknown"}')
    print(f'executables in {found / "lib" / PACKAGE}: {", ".join(nodes)}')
    return 0
