"""ament_python setup for fmm_ros: the `fmm` CLI and one console script per ROS node."""

from glob import glob

from setuptools import find_packages, setup

PACKAGE = 'fmm_ros'

# ROS node executables (`ros2 run fmm_ros <name>`); colcon installs them to lib/fmm_ros.
NODES = {
}

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(include=[PACKAGE, f'{PACKAGE}.*']),
    data_files=[
        ('share/ament_index/resource_index/packages', [f'resource/{PACKAGE}']),
        (f'share/{PACKAGE}', ['package.xml']),
        (f'share/{PACKAGE}/config', glob('config/*.yaml')),
        (f'share/{PACKAGE}/launch_scripts', glob('launch_scripts/*.py')),
    ],
    python_requires='>=3.10',
    install_requires=['setuptools', 'numpy', 'scipy', 'numba', 'pyuff', 'matplotlib'],
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
