"""
ROS 2 adapters (thin): ``sensor_driver``, ``kf_estimator``, ``identifier``.

Every algorithm lives in the plain modules (rig, signals, kalman, identify); the nodes only move messages, check
their inputs, keep records and report ``/diagnostics``.

Modules without ROS (the tests import them; rclpy never enters the pytest process): ``*_core`` (each node's data path
and its ``SPECS``), :mod:`.specs` (parameter specs, validation, params/*.yaml), :mod:`.topics`, :mod:`.status`
(diagnostic items), :mod:`.monitor` (input-stream checks), :mod:`.runs` (which run a block belongs to), :mod:`.dds`
(DDS on loopback).  With rclpy: :mod:`.declare` (parameters on a node), :mod:`.qos`, :mod:`.diagnostics`
(publishing them), :mod:`.process` (start, spin, stop, bounded teardown) and the three node modules.
"""
from .. import blas_threads  # noqa: F401  (each node is a process: one BLAS thread unless the user set one)
