"""
DDS transport on this machine only (no ROS import).

``params/fastdds_localhost.xml`` (:data:`FASTDDS_PROFILE`, :func:`loopback_dds_env`) confines Fast DDS to 127.0.0.1
and shared memory; the Makefile, the demo and the tests choose it.
"""
from __future__ import annotations

from pathlib import Path

FASTDDS_PROFILE = Path(__file__).resolve().parents[2] / 'params' / 'fastdds_localhost.xml'


def fastdds_profile() -> Path | None:
    """
    Return the Fast DDS profile that confines DDS to loopback; None when neither copy exists.

    ``params/fastdds_localhost.xml`` of the source tree, else the installed copy (``share/bearing_id/params``, colcon).
    """
    if FASTDDS_PROFILE.is_file():
        return FASTDDS_PROFILE
    try:
        from ament_index_python.packages import get_package_share_directory, PackageNotFoundError
    except ImportError:
        return None
    try:
        p = Path(get_package_share_directory('bearing_id')) / 'params' / FASTDDS_PROFILE.name
    except PackageNotFoundError:
        return None
    return p if p.is_file() else None


def loopback_dds_env(profile: Path | str | None = None) -> dict:
    """
    Return the environment variables that confine DDS to 127.0.0.1 and shared memory (no socket elsewhere).

    * ``FASTRTPS_DEFAULT_PROFILES_FILE`` / ``FASTDDS_DEFAULT_PROFILES_FILE`` = the profile (Fast DDS 2.x reads the
      first, 3.x the second): UDPv4 restricted to 127.0.0.1 + SHM, discovery by unicast to 127.0.0.1, no multicast;
    * ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` (discovery by unicast to this host only; the project's rule for
      every ROS process of its tests, demo and CI).  In that mode rmw_fastrtps (Jazzy) still opens two send-only
      UDP sockets outside loopback (0.0.0.0 and the external interface, ephemeral ports) whatever the profile says;
      every socket that *receives* DDS traffic is on 127.0.0.1.  (``SYSTEM_DEFAULT`` with this profile leaves no
      socket outside loopback at all -- a choice for a plant's own launch environment.)
    """
    path = Path(profile) if profile is not None else fastdds_profile()
    if path is None or not Path(path).is_file():
        raise FileNotFoundError(f'Fast DDS profile not found: {path or FASTDDS_PROFILE}')
    return {'FASTRTPS_DEFAULT_PROFILES_FILE': str(path), 'FASTDDS_DEFAULT_PROFILES_FILE': str(path),
            'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST'}
