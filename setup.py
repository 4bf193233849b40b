"""
ament_python package bearing_id (ROS 2 Jazzy), also pip-installable (editable) into a plain venv.

colcon / ament: the data_files put the resource-index marker, package.xml, params/*.yaml and the Fast DDS profile
params/fastdds_localhost.xml under share/bearing_id, and setup.cfg puts the console scripts in lib/bearing_id so that
``ros2 run bearing_id <node>`` finds them.
"""
from glob import glob

from setuptools import find_packages, setup

package_name = 'bearing_id'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/params', sorted(glob('params/*.yaml') + glob('params/*.xml'))),
    ],
    install_requires=['setuptools'],
    zip_safe=False,
    maintainer='bearing_id maintainers',
    maintainer_email='bearing_id@example.com',
    description='Identify the stiffness and damping coefficients of the journal bearings of a flexible rotor '
                'from shaft displacement measured at one location (Kalman filter + least squares).',
    license='Apache-2.0',
    python_requires='>=3.10',
    tests_require=['pytest'],
    entry_points={
        'console_scripts': [
            'sensor_driver = bearing_id.nodes.sensor_driver:main',
            'kf_estimator = bearing_id.nodes.kf_estimator:main',
            'identifier = bearing_id.nodes.identifier:main',
            'bearing-id = bearing_id.cli:main',
        ],
    },
)
