"""
ament_python package bearing_id (ROS 2 Jazzy); metadata, dependencies and entry points are in pyproject.toml.

colcon / ament: the data_files put the resource-index marker, package.xml, params/*.yaml and the Fast DDS profile
params/fastdds_localhost.xml under share/bearing_id, and setup.cfg puts the console scripts in lib/bearing_id so that
``ros2 run bearing_id <node>`` finds them.  The interface definitions (msg_defs/msg/*.msg) go to share/bearing_id/msg
too, so that a plain ``pip install .`` reads and writes bags without the built interface package.
"""
from glob import glob

from setuptools import setup

package_name = 'bearing_id'

setup(
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/params', sorted(glob('params/*.yaml') + glob('params/*.xml'))),
        ('share/' + package_name + '/msg', sorted(glob('msg_defs/msg/*.msg'))),
    ],
    zip_safe=False,
)
