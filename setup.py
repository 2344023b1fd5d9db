"""ament_python package setup for workzone_ros.

On a machine with ROS 2 Jazzy system packages, build with ``colcon build``: the
``wheels`` extra is not pulled.  On a machine without ROS, ``pip install -e .[wheels,test]``
(what ``make`` does) brings the ROS 2 Jazzy Python stack from PyPI.
"""
from glob import glob

from setuptools import find_packages, setup

PACKAGE = 'workzone_ros'

# One console entry point per node, plus the ``workzone-ros`` CLI.
NODES = {
    'lidar_cluster': 'workzone_ros.nodes.lidar_cluster:main',
    'projector': 'workzone_ros.nodes.projector:main',
    'color_detector': 'workzone_ros.nodes.color_detector:main',
    'tracker': 'workzone_ros.nodes.tracker:main',
    'classifier': 'workzone_ros.nodes.classifier:main',
    'fusion': 'workzone_ros.nodes.fusion:main',
}

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml']),
        ('share/' + PACKAGE + '/config', glob('config/*.yaml')),
        ('share/' + PACKAGE + '/config/scenarios', glob('config/scenarios/*.yaml')),
        ('share/' + PACKAGE + '/config/models', glob('config/models/*')),
    ],
    package_data={PACKAGE: ['py.typed']},
    python_requires='>=3.10',
    install_requires=[
        'setuptools',
        'numpy>=1.24',
        'scipy>=1.10',
        # compiled inner loops of the sign measurement (workzone_ros/core/kernels.py)
        'numba>=0.59',
        'scikit-learn>=1.3',
        # Haar-like features and integral images of the sign-shape cascade
        # (workzone_ros/core/general/shapes.py)
        'scikit-image>=0.22',
        'opencv-python-headless>=4.8',
        'msgspec>=0.18',
        'PyYAML>=6',
        'rosbags>=0.10',
    ],
    extras_require={
        'wheels': [
            'ros-rclpy==7.1.6',
            'ros-common-interfaces==5.3.6',
            'ros-rmw-fastrtps-cpp==8.4.3',
        ],
        'test': [
            'pytest>=7',
            'pytest-timeout>=2',
            'ruff>=0.4',
            # LZF decompression for binary_compressed PCD files (the real PJLab LiDAR scenes
            # in the tests); workzone_ros.core.pcd says how to install it when missing.
            'python-lzf>=0.2.6',
            # generated malformed messages for every subscription (test/faults and
            # `workzone-ros evaluate faults`; docs/faults.md)
            'hypothesis>=6.100',
        ],
        # `workzone-ros train cnn` only: the CNN sign classifier's trainer and its ONNX
        # export (the model runs on OpenCV's dnn module; the nodes never import these)
        'cnn': [
            'torch>=2.2',
            'onnx>=1.15',
        ],
    },
    zip_safe=True,
    maintainer='workzone_ros developers',
    maintainer_email='dev@workzone-ros.invalid',
    description='Highway work-zone perception from camera and LiDAR (ROS 2 Jazzy, rclpy).',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [f'{name} = {target}' for name, target in NODES.items()]
        + ['workzone-ros = workzone_ros.cli:main'],
    },
)
