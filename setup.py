"""ament_python setup for fmm_ros: the `fmm` CLI and one console script per ROS node."""

from glob import glob
from pathlib import Path

from setuptools import find_packages, setup
from setuptools.command.build_py import build_py

PACKAGE = 'fmm_ros'

# ROS node executables (`ros2 run fmm_ros <name>`); colcon installs them to lib/fmm_ros.
NODES = {
    'hammer_sim': 'fmm_ros.ros.nodes.hammer_sim:main',
    'rig_sim': 'fmm_ros.ros.nodes.rig_sim:main',
    'analyzer': 'fmm_ros.ros.nodes.analyzer:main',
    'fitter': 'fmm_ros.ros.nodes.fitter:main',
    'recorder': 'fmm_ros.ros.nodes.recorder:main',
    'player': 'fmm_ros.ros.nodes.player:main',
    'daq': 'fmm_ros.ros.nodes.daq:main',
    'live': 'fmm_ros.ros.nodes.live:main',
    'foxglove_server': 'fmm_ros.ros.nodes.foxglove_server:main',
    'station': 'fmm_ros.ros.nodes.station:main',
}


class BuildPyWithInterfaces(build_py):
    """Also copy fmm_interfaces/msg/*.msg into the built package (not into the source tree).

    Bag I/O builds its message types from these files; a plain `pip install` on a laptop
    without ROS has no ament index to find them in, so they travel as package data,
    generated from the one copy in fmm_interfaces/. Editable installs read them in place.
    """

    def run(self) -> None:
        """Build the package as usual, then add the .msg files to it."""
        super().run()
        if self.editable_mode:
            return
        target = Path(self.build_lib) / PACKAGE / 'interface_definitions' / 'msg'
        self.mkpath(str(target))
        for msg in sorted(Path('fmm_interfaces', 'msg').glob('*.msg')):
            self.copy_file(str(msg), str(target / msg.name))


setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(include=[PACKAGE, f'{PACKAGE}.*']),
    # The station's page, served as files (uPlot vendored beside it: it works offline).
    package_data={f'{PACKAGE}.station': ['static/*.*', 'static/vendor/uplot/*']},
    data_files=[
        ('share/ament_index/resource_index/packages', [f'resource/{PACKAGE}']),
        (f'share/{PACKAGE}', ['package.xml']),
        (f'share/{PACKAGE}/config', glob('config/*.yaml')),
        (f'share/{PACKAGE}/config/sros2', glob('config/sros2/*.xml')),
        (f'share/{PACKAGE}/config/foxglove', glob('config/foxglove/*.json')),
        (f'share/{PACKAGE}/launch_scripts', glob('launch_scripts/*.py')),
        # `ros2 launch fmm_ros sim_rig.launch.xml` in a sourced workspace.
        (f'share/{PACKAGE}/launch', glob('launch/*.launch.xml')),
    ],
    python_requires='>=3.10',
    # Everything fmm_ros imports but ROS itself (test_package checks it against the code).
    install_requires=[
        'setuptools',
        'numpy',
        'scipy',
        'numba',
        'pyuff',
        'pyyaml',
        'rosbags',
        'ruamel.yaml.clib',  # rosbags' YAML parsed by libyaml: ~25 ms a bag opened
        'mcap',
        'zstandard',
        'lz4',
        'nptdms',
        'h5py',
        'clevercsv',
        'chardet',
        'tqdm',
        'matplotlib',
        'pillow',
        'foxglove-sdk',
        'dask',
        'distributed',
        'pyarrow',
        'tornado',
    ],
    cmdclass={'build_py': BuildPyWithInterfaces},
    zip_safe=True,
    maintainer='fmm_ros maintainers',
    maintainer_email='fmm@example.org',
    description='Impact-hammer FRF testing and friction identification on the FMM.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'fmm = fmm_ros.cli:main',
            *(f'{name} = {target}' for name, target in NODES.items()),
        ],
    },
)
