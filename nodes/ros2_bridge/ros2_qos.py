"""ROS 2's QoS profiles as Cyclone DDS QoS, and the Cyclone configuration of the bridge's network interface.

``rmw_qos_profile_default`` is RELIABLE, VOLATILE, KEEP_LAST 10; ``rmw_qos_profile_sensor_data`` BEST_EFFORT,
VOLATILE, KEEP_LAST 5; ``rmw_qos_profile_services_default`` RELIABLE, VOLATILE, KEEP_LAST 10. A latched topic
(``camera_info`` of many drivers, ``/tf_static``) is RELIABLE, TRANSIENT_LOCAL, KEEP_LAST 1. Every writer and
reader here offers plain CDR only (``DataRepresentation`` XCDR1), which is what ``rmw_cyclonedds_cpp`` writes
and reads.
"""
from __future__ import annotations

from xml.sax.saxutils import quoteattr

from cyclonedds.qos import Policy, Qos
from cyclonedds.util import duration

__all__ = ["PROFILES", "ros2_qos", "cyclone_config_xml"]

#: ROS 2 profile name -> (reliable, transient_local, depth).
PROFILES = {
    "default": (True, False, 10),
    "sensor_data": (False, False, 5),
    "services_default": (True, False, 10),
    "latched": (True, True, 1),
}


def ros2_qos(profile: str) -> Qos:
    """Cyclone QoS of a ROS 2 profile name (one of :data:`PROFILES`).

    Raises
    ------
    ValueError
        For an unknown name, listing the known ones.
    """
    if profile not in PROFILES:
        raise ValueError(f"unknown ROS 2 QoS profile {profile!r}; expected one of {', '.join(PROFILES)}")
    reliable, transient_local, depth = PROFILES[profile]
    return Qos(
        Policy.Reliability.Reliable(max_blocking_time=duration(milliseconds=100)) if reliable
        else Policy.Reliability.BestEffort,
        Policy.Durability.TransientLocal if transient_local else Policy.Durability.Volatile,
        Policy.History.KeepLast(depth),
        Policy.DataRepresentation(use_cdrv0_representation=True),
    )


def cyclone_config_xml(interface: str = "", peers: tuple = (), *, max_message_size: int = 0) -> str | None:
    """A Cyclone DDS configuration (XML text) for one network interface and unicast peers, or None.

    Parameters
    ----------
    interface : str
        Network interface name (``lo``, ``eth0``) or address; "" leaves it to Cyclone (or ``CYCLONEDDS_URI``).
    peers : sequence of str
        Unicast discovery peers (``127.0.0.1``); when given, multicast is switched off and participants take
        an automatic index so that peers on one host find each other's ports.
    max_message_size : int
        Largest RTPS message in bytes (``0``: Cyclone's default, 14720 B); up to 65500 on loopback.

    Returns
    -------
    str or None
        None when nothing is set: Cyclone then reads ``CYCLONEDDS_URI`` as usual.
    """
    if not interface and not peers and not max_message_size:
        return None
    general = []
    if interface:
        general.append(f"<Interfaces><NetworkInterface name={quoteattr(interface)}/></Interfaces>")
    if peers:
        general.append("<AllowMulticast>false</AllowMulticast>")
    if max_message_size:
        general.append(f"<MaxMessageSize>{int(max_message_size)}B</MaxMessageSize>")
    discovery = ""
    if peers:
        peer_xml = "".join(f"<Peer Address={quoteattr(peer)}/>" for peer in peers)
        discovery = (f"<Discovery><ParticipantIndex>auto</ParticipantIndex>"
                     f"<MaxAutoParticipantIndex>50</MaxAutoParticipantIndex><Peers>{peer_xml}</Peers></Discovery>")
    return (f'<CycloneDDS><Domain id="any"><General>{"".join(general)}</General>{discovery}</Domain>'
            f"</CycloneDDS>")
