"""
bearing_id: identify journal-bearing stiffness and damping of a flexible rotor from shaft displacement.

The physics (rotor model, bearing theory, Kalman filter, identification, diagnosis) lives in plain modules that
import no ROS; ``bearing_id.nodes`` are thin ROS 2 adapters around them and ``bearing-id`` is the offline CLI.
Conventions (signs, axes, phasors, node numbers, units): :mod:`bearing_id.conventions`.
"""
__version__ = '0.1.0'
