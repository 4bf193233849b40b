"""
ROS 2 adapters (thin): ``sensor_driver``, ``kf_estimator``, ``identifier``.

Every algorithm lives in the plain modules (rig, signals, kalman, identify); the nodes only move messages, check
their inputs, keep records and report ``/diagnostics``.  Shared parameter handling, input checks and the process
main loop are in :mod:`bearing_id.nodes.common`.
"""
from .. import blas_threads  # noqa: F401  (each node is a process: one BLAS thread unless the user set one)
