"""Shared pytest set-up.

* Puts this directory on sys.path so tests can ``import rosutil`` (the ROS subprocess helpers).
* Keeps DDS discovery on this machine for anything started from the test process
  (``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``) and gives the process its own ``ROS_DOMAIN_ID`` only when a ROS
  helper asks for one (see :func:`rosutil.ros_env`).  rclpy itself is never imported in the pytest process.
* Cleans Fast DDS shared memory left by killed participants at the end of the session.
* Registers the ``slow`` and ``ros`` markers.
"""
from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
if str(HERE) not in sys.path:
    sys.path.insert(0, str(HERE))

os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")


def pytest_configure(config):
    config.addinivalue_line("markers", "slow: takes more than ~20 s (still run by `make test`)")
    config.addinivalue_line("markers", "ros: starts ROS 2 processes (rclpy in subprocesses, see test/rosutil.py)")


@pytest.fixture(scope="session", autouse=True)
def _fastdds_shm_cleanup():
    yield
    import rosutil

    if rosutil._domain_lock is not None:  # only when this session started ROS processes
        rosutil.shm_clean()


@pytest.fixture(scope="session")
def rig():
    """The packaged paper rig (params/rig.yaml)."""
    from bearing_id.params import load_rig
    return load_rig()


@pytest.fixture(scope="session")
def model(rig):
    """The FE rotor model of the packaged rig."""
    from bearing_id.rotor.assembly import RotorModel
    return RotorModel.from_params(rig)
