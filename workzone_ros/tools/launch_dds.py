"""The launcher's Fast DDS participant profile: shared memory with large segments, written once
per user (:func:`fastdds_shm_profile`) and set for this process and its children
(:func:`apply_dds_profile`, ``workzone-ros launch --dds-profile``).
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import Optional

from workzone_ros.tools.launch_nodes import LaunchError

__all__ = ['fastdds_shm_profile', 'apply_dds_profile']


# Fast DDS participant profile: shared memory with 32 MB segments (+ UDP for everything else).
# The default 512 kB segment sends images and clouds over fragmented UDP, where best-effort
# (sensor-data) subscribers lose most of them (compare ``workzone-ros bench transport``
# with and without ``--default-transport``).
_SHM_PROFILE = """<?xml version="1.0" encoding="UTF-8" ?>
<profiles xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles">
  <transport_descriptors>
    <transport_descriptor>
      <transport_id>workzone_shm</transport_id>
      <type>SHM</type>
      <segment_size>{segment}</segment_size>
    </transport_descriptor>
    <transport_descriptor>
      <transport_id>workzone_udp</transport_id>
      <type>UDPv4</type>
    </transport_descriptor>
  </transport_descriptors>
  <participant profile_name="workzone_participant" is_default_profile="true">
    <rtps>
      <userTransports>
        <transport_id>workzone_shm</transport_id>
        <transport_id>workzone_udp</transport_id>
      </userTransports>
      <useBuiltinTransports>false</useBuiltinTransports>
    </rtps>
  </participant>
</profiles>
"""


def fastdds_shm_profile(segment_mb: int = 32) -> Path:
    """Write (once) the large-segment shared-memory Fast DDS profile; returns its path."""
    import tempfile
    text = _SHM_PROFILE.format(segment=int(segment_mb) * 1024 * 1024)
    path = Path(tempfile.gettempdir()) / f'workzone_fastdds_shm_{os.getuid()}_{segment_mb}.xml'
    if not path.is_file() or path.read_text() != text:
        tmp = path.with_suffix(f'.{os.getpid()}.tmp')
        tmp.write_text(text)
        tmp.replace(path)
    return path


def apply_dds_profile(choice: str) -> Optional[str]:
    """Set ``FASTRTPS_DEFAULT_PROFILES_FILE`` for this process and its children.

    Must run before rclpy creates a participant in this process.

    Args:
        choice: ``'shm'`` (built-in large-segment profile, unless the user already set a
            profile file), ``'none'``, or the path of a Fast DDS XML file.

    Returns:
        The profile file in effect, or None.
    """
    current = os.environ.get('FASTRTPS_DEFAULT_PROFILES_FILE')
    if choice == 'none':
        return current
    if 'fastrtps' not in os.environ.get('RMW_IMPLEMENTATION', 'rmw_fastrtps_cpp'):
        return current
    if choice == 'shm':
        if current:
            return current
        path = str(fastdds_shm_profile())
    else:
        if not Path(choice).is_file():
            raise LaunchError(f'Fast DDS profile not found: {choice}')
        path = str(Path(choice).resolve())
    os.environ['FASTRTPS_DEFAULT_PROFILES_FILE'] = path
    return path
