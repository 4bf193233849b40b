"""
Shared pytest set-up.

* Puts this directory on sys.path so tests can ``import rosutil`` (the ROS subprocess helpers).
* Keeps DDS discovery on this machine for anything started from the test process
  (``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``) and gives the process its own ``ROS_DOMAIN_ID`` only when a ROS
  helper asks for one (see :func:`rosutil.ros_env`).  rclpy itself is never imported in the pytest process.
* Cleans Fast DDS shared memory left by killed participants at the end of the session.
* Prints the OpenBLAS kernel and thread count numpy and scipy run with (``.ci/run`` runs the numeric tests on two).
* Registers the ``slow`` and ``ros`` markers, and the ``linter``, ``flake8`` and ``pep257`` markers of the ament
  lint tests (their pytest plugins register them too when installed).
"""
from __future__ import annotations

import os
from pathlib import Path
import sys

import pytest

HERE = Path(__file__).resolve().parent
if str(HERE) not in sys.path:
    sys.path.insert(0, str(HERE))

os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.setdefault('OPENBLAS_NUM_THREADS', '1')


def pytest_configure(config):
    config.addinivalue_line('markers', 'slow(reason): takes more than ~10 s for the stated reason (make test runs it; '
                                       '-m "not slow" leaves it out)')
    config.addinivalue_line('markers', 'ros: starts ROS 2 processes (rclpy in subprocesses, see test/rosutil.py)')
    config.addinivalue_line('markers', 'linter: marks tests as linter checks')
    config.addinivalue_line('markers', 'flake8: marks tests checking for flake8 compliance')
    config.addinivalue_line('markers', 'pep257: marks tests checking for PEP 257 compliance')


def pytest_report_header(config):
    """Name the BLAS kernels in use: a rounding-dependent failure says which kernel it failed on."""
    import numpy  # noqa: F401  (loads numpy's OpenBLAS)
    import scipy.linalg  # noqa: F401  (and scipy's)
    try:
        from threadpoolctl import threadpool_info
    except ImportError:                     # colcon test without the project's requirements
        return 'OpenBLAS kernel: unknown (threadpoolctl is not installed)'
    blas = sorted({(i.get('architecture') or '?', i.get('num_threads')) for i in threadpool_info()
                   if i.get('internal_api') == 'openblas'})
    return 'OpenBLAS (kernel, threads): ' + ', '.join(f'{a} x{n}' for a, n in blas)


@pytest.fixture(scope='session', autouse=True)
def _fastdds_shm_cleanup():
    yield
    import rosutil

    if rosutil._domain_lock is not None:  # only when this session started ROS processes
        rosutil.shm_clean()


@pytest.fixture(scope='session')
def rig():
    """Return the packaged paper rig, params/rig.yaml."""
    from bearing_id.config.params import load_rig
    return load_rig()


@pytest.fixture(scope='session')
def model(rig):
    """Build the FE rotor model of the packaged rig."""
    from bearing_id.rotor.assembly import RotorModel
    return RotorModel.from_params(rig)
