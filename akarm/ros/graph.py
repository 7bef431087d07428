"""``ros_discovery_info``: what ties a DDS participant's readers and writers to a ROS 2 node's name.

``ros2 topic list`` and ``ros2 action list`` see akarm's endpoints from DDS discovery alone; but
``ros2 node list``, ``ros2 node info`` and ``ros2 action info`` ask ROS 2's graph cache
(rmw_dds_common ``graph_cache.cpp``), which learns which endpoint belongs to which node from the
``rmw_dds_common/msg/ParticipantEntitiesInfo`` each participant publishes on the DDS topic
``ros_discovery_info`` (no ``rt/`` prefix; reliable, transient local, keep last 1), as
rmw_cyclonedds_cpp does in ``rmw_node.cpp``:

- ``gid``: the participant's GUID; ``node_entities_info_seq``: one entry per node, with its
  namespace (``/`` for none) and name, and the GIDs of its readers and of its writers (a service:
  its request reader and its reply writer);
- a GID is the 16-byte DDS GUID, padded with zeros to ``RMW_GID_STORAGE_SIZE``: 24 bytes on humble,
  16 from iron on (rmw_dds_common ``Gid.msg``: ``char[24]``, then ``char[16]``).

The discovery writer itself belongs to the participant, not to the node, and is not listed.
"""

# no `from __future__ import annotations`: cyclonedds reads the field types at run time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import cyclonedds.idl.annotations as annotate
from cyclonedds.idl import IdlStruct
from cyclonedds.pub import DataWriter
from cyclonedds.topic import Topic

from akarm.ros.action_types import check_distro
from akarm.ros.dds import Node, latched_qos, qos, ros_name

if TYPE_CHECKING:  # for a type checker these are lists and str; cyclonedds reads its own at run time
    sequence = list
    uint8_16 = list[int]
    uint8_24 = list[int]
    str_256 = str
else:
    from cyclonedds.idl.types import array, bounded_str, sequence, uint8

    uint8_16, uint8_24, str_256 = array[uint8, 16], array[uint8, 24], bounded_str[256]

__all__ = ["DISCOVERY_TOPIC", "DiscoveryInfo", "GidHumble", "GidJazzy", "participant_info_type"]

#: The DDS topic ROS 2's graph cache reads.
DISCOVERY_TOPIC = "ros_discovery_info"
_PKG = "rmw_dds_common::msg::dds_::"


@dataclass
@annotate.final
class GidHumble(IdlStruct, typename=_PKG + "Gid_"):
    data: uint8_24 = field(default_factory=lambda: [0] * 24)


@dataclass
@annotate.final
class NodeEntitiesInfoHumble(IdlStruct, typename=_PKG + "NodeEntitiesInfo_"):
    node_namespace: str_256 = ""
    node_name: str_256 = ""
    reader_gid_seq: sequence[GidHumble] = field(default_factory=list)
    writer_gid_seq: sequence[GidHumble] = field(default_factory=list)


@dataclass
@annotate.final
class ParticipantEntitiesInfoHumble(IdlStruct, typename=_PKG + "ParticipantEntitiesInfo_"):
    gid: GidHumble = field(default_factory=GidHumble)
    node_entities_info_seq: sequence[NodeEntitiesInfoHumble] = field(default_factory=list)


@dataclass
@annotate.final
class GidJazzy(IdlStruct, typename=_PKG + "Gid_"):
    data: uint8_16 = field(default_factory=lambda: [0] * 16)


@dataclass
@annotate.final
class NodeEntitiesInfoJazzy(IdlStruct, typename=_PKG + "NodeEntitiesInfo_"):
    node_namespace: str_256 = ""
    node_name: str_256 = ""
    reader_gid_seq: sequence[GidJazzy] = field(default_factory=list)
    writer_gid_seq: sequence[GidJazzy] = field(default_factory=list)


@dataclass
@annotate.final
class ParticipantEntitiesInfoJazzy(IdlStruct, typename=_PKG + "ParticipantEntitiesInfo_"):
    gid: GidJazzy = field(default_factory=GidJazzy)
    node_entities_info_seq: sequence[NodeEntitiesInfoJazzy] = field(default_factory=list)


_TYPES: dict[str, tuple[Any, Any, Any, int]] = {
    "humble": (ParticipantEntitiesInfoHumble, NodeEntitiesInfoHumble, GidHumble, 24),
    "jazzy": (ParticipantEntitiesInfoJazzy, NodeEntitiesInfoJazzy, GidJazzy, 16),
}


def participant_info_type(distro: str) -> Any:
    """The ParticipantEntitiesInfo type of ``distro`` (24-byte GIDs on humble, 16 after)."""
    return _TYPES["humble" if check_distro(distro) == "humble" else "jazzy"][0]


class DiscoveryInfo:
    """Publishes ``ros_discovery_info`` for the node ``node_name`` of ``node``: every endpoint in
    ``node.endpoints`` when :meth:`publish` is called (call it once they are all open)."""

    def __init__(self, node: Node, node_name: str, distro: str) -> None:
        ros_name(node.namespace, node_name)  # a node name is a ROS 2 name token
        self.node = node
        self.node_name = node_name
        self.info_type, self._node_type, self._gid_type, self._gid_size = \
            _TYPES["humble" if check_distro(distro) == "humble" else "jazzy"]
        topic = Topic(node.participant, DISCOVERY_TOPIC, self.info_type, qos=qos())
        self.writer = DataWriter(node.participant, topic, qos=latched_qos())

    def gid(self, entity: Any) -> Any:
        """The GID of a DDS entity (participant, reader, writer): its GUID, zero-padded."""
        return self._gid_type(list(entity.guid.bytes) + [0] * (self._gid_size - 16))

    def message(self) -> Any:
        """The ParticipantEntitiesInfo of the node as it is now."""
        readers = [self.gid(e) for e in self.node.endpoints if not isinstance(e, DataWriter)]
        writers = [self.gid(e) for e in self.node.endpoints if isinstance(e, DataWriter)]
        info = self._node_type("/" + self.node.namespace, self.node_name, readers, writers)
        return self.info_type(self.gid(self.node.participant), [info])

    def publish(self) -> None:
        self.writer.write(self.message())
