"""What rmw_zenoh (ROS 2's Zenoh middleware, Jazzy and later) puts on the wire besides the CDR payload:
topic keys, the attachment of every sample, liveliness tokens (the ROS graph), entity GIDs.

Pure functions of strings and integers; no Zenoh, no ROS. Followed from rmw_zenoh_cpp's design document
(docs/design.md: "Topic and Service name mapping to Zenoh key expressions", "Graph Cache", "Publishers")
and its sources (``liveliness_utils.cpp``: `TopicInfo`, `Entity`, `mangle_name`, `qos_to_keyexpr`;
``attachment_helpers.cpp``; ``qos.cpp``; ``rmw_node_data.cpp``, ``rmw_publisher_data.cpp``).

**Topic key.** ``<domain_id>/<fully qualified name without its leading and trailing "/">/<DDS type
name>/<type hash>``, e.g. ``0/dpgw/odom/nav_msgs::msg::dds_::Odometry_/RIHS01_3cc9…``. The DDS type
name of ``pkg/msg/Name`` is ``pkg::msg::dds_::Name_``; the hash is REP-2011's RIHS01 (rosbags computes
it: `rosbags.typesys.store.Typestore.hash_rihs01`). A key per type and hash: a subscriber of another
type, or of another definition of the same type, never matches.

**Attachment** of every published sample, written with Zenoh's serializer (`zenoh::ext::Serializer`):
an int64 sequence number (1 for a publisher's first sample), an int64 source timestamp (ns since the
Unix epoch, this computer's clock when the sample is published) and the publisher's 16-byte GID as a
sequence: its length as a LEB128 varint (one byte, 16) then the bytes. Little-endian; 33 bytes::

    offset 0   int64 LE   sequence number
    offset 8   int64 LE   source timestamp (ns, UTC)
    offset 16  uint8      16 (the GID's length, LEB128)
    offset 17  16 bytes   GID

**Liveliness tokens** (how ``ros2 node list`` / ``ros2 topic list`` find entities): under the hermetic
admin space ``@ros2_lv``, a node's is
``@ros2_lv/<domain>/<zid>/<node id>/<node id>/NN/<enclave>/<namespace>/<node name>`` and a publisher's
(``MP``) or subscription's (``MS``) continues ``…/<entity id>/MP/<enclave>/<namespace>/<node name>/<topic>/
<type name>/<type hash>/<qos>``. Every name part is *mangled*: each ``/`` becomes ``%`` (the default
enclave ``/`` is ``%``, the namespace ``/dpgw`` is ``%dpgw``, the topic ``/dpgw/odom`` is
``%dpgw%odom``). ``<zid>`` is the Zenoh session id as Zenoh prints it; node and entity ids are decimal
counters unique within the session.

**QoS in a token** (`qos_to_keyexpr`): ``<reliability>:<durability>:<history>,<depth>:<deadline s>,
<deadline ns>:<lifespan s>,<lifespan ns>:<liveliness>,<lease s>,<lease ns>``, each field empty when it
equals rmw_zenoh's default (reliable, volatile, keep-last, depth 42, infinite durations, automatic
liveliness) and otherwise the rmw enum's number. Keep-last 10, reliable, volatile is ``::,10:,:,:,,``.

**GID** of an entity: XXH3-128 of its liveliness token (the key text), the low 64 bits then the high 64
bits, each little-endian: the GID rmw_zenoh computes for the same entity, so the attachment names the
publisher ``ros2 topic info -v`` shows.
"""

from __future__ import annotations

import re
import struct
from dataclasses import dataclass, replace
from typing import Final

ADMIN_SPACE: Final = "@ros2_lv"
NODE, PUBLISHER, SUBSCRIPTION = "NN", "MP", "MS"
DEFAULT_ENCLAVE: Final = "/"
"""The SROS enclave of a node that is given none (rcl's default), mangled to ``%``."""

ATTACHMENT = struct.Struct("<qqB16s")
"""Sequence number, source timestamp, GID length (16, a one-byte LEB128 varint), GID."""
GID_SIZE: Final = 16

# rmw's QoS enum values (rmw/types.h) and rmw_zenoh's defaults (qos.cpp)
RELIABLE, BEST_EFFORT = 1, 2
TRANSIENT_LOCAL, VOLATILE = 1, 2
KEEP_LAST, KEEP_ALL = 1, 2
DEFAULT_DEPTH: Final = 42

_TOKEN = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
"""One token of a ROS name: letters, digits and underscores, not starting with a digit."""


def dds_type_name(ros_type: str) -> str:
    """``nav_msgs/msg/Odometry`` → ``nav_msgs::msg::dds_::Odometry_`` (the name rmw_zenoh keys on)."""
    package, kind, name = ros_type.split("/")
    return f"{package}::{kind}::dds_::{name}_"


def ros_type_name(dds_name: str) -> str:
    """The inverse of `dds_type_name`."""
    package, kind, dds, name = dds_name.split("::")
    if dds != "dds_" or not name.endswith("_"):
        raise ValueError(f"not a DDS type name of a ROS type: {dds_name!r}")
    return f"{package}/{kind}/{name[:-1]}"


def is_ros_name(name: str, *, absolute: bool) -> bool:
    """A valid ROS 2 name without substitutions: tokens joined by ``/``; ``absolute``: starting with ``/``
    (a namespace; ``/`` alone is the root), otherwise relative (a topic under the node's namespace)."""
    if absolute:
        if name == "/":
            return True
        if not name.startswith("/"):
            return False
        name = name[1:]
    return all(_TOKEN.fullmatch(t) for t in name.split("/"))


def fully_qualified(namespace: str, name: str) -> str:
    """The fully qualified name of ``name`` in ``namespace``: an absolute name stays as it is."""
    if name.startswith("/"):
        return name
    return f"/{name}" if namespace == "/" else f"{namespace}/{name}"


def topic_key(domain_id: int, topic: str, ros_type: str, type_hash: str) -> str:
    """The Zenoh key of a topic: ``<domain>/<topic without its slashes at the ends>/<DDS type>/<hash>``."""
    return f"{domain_id}/{topic.strip('/')}/{dds_type_name(ros_type)}/{type_hash}"


def mangle(name: str) -> str:
    """A name as one key chunk: every ``/`` becomes ``%``."""
    return name.replace("/", "%")


def demangle(chunk: str) -> str:
    return chunk.replace("%", "/")


@dataclass(frozen=True)
class Qos:
    """The QoS a token advertises (rmw enum numbers; durations are not set: infinite, the default)."""

    reliability: int = RELIABLE
    durability: int = VOLATILE
    history: int = KEEP_LAST
    depth: int = 10

    def keyexpr(self) -> str:
        """rmw_zenoh's compact form: a field equal to the default is left empty."""

        def field(value: int, default: int) -> str:
            return "" if value == default else str(value)

        return (
            f"{field(self.reliability, RELIABLE)}:{field(self.durability, VOLATILE)}:"
            f"{field(self.history, KEEP_LAST)},{field(self.depth, DEFAULT_DEPTH)}:,:,:,,"
        )


def node_token(
    domain_id: int, zid: str, node_id: int, namespace: str, node: str, enclave: str = DEFAULT_ENCLAVE
) -> str:
    """A node's liveliness token (its id appears twice: as the node id and as the entity id)."""
    return (
        f"{ADMIN_SPACE}/{domain_id}/{zid}/{node_id}/{node_id}/{NODE}/{mangle(enclave)}/{mangle(namespace)}/"
        f"{mangle(node)}"
    )


def entity_token(
    domain_id: int,
    zid: str,
    node_id: int,
    entity_id: int,
    kind: str,
    namespace: str,
    node: str,
    topic: str,
    ros_type: str,
    type_hash: str,
    qos: Qos,
    enclave: str = DEFAULT_ENCLAVE,
) -> str:
    """A publisher's (``MP``) or subscription's (``MS``) liveliness token; ``topic`` fully qualified."""
    return (
        f"{ADMIN_SPACE}/{domain_id}/{zid}/{node_id}/{entity_id}/{kind}/{mangle(enclave)}/{mangle(namespace)}/"
        f"{mangle(node)}/{mangle(topic)}/{dds_type_name(ros_type)}/{type_hash}/{qos.keyexpr()}"
    )


@dataclass(frozen=True)
class Token:
    """A liveliness token read back (`parse_token`); the topic fields are empty for a node."""

    domain_id: int
    zid: str
    node_id: str
    entity_id: str
    kind: str
    enclave: str
    namespace: str
    node: str
    topic: str = ""
    dds_type: str = ""
    type_hash: str = ""
    qos: str = ""


def parse_token(key: str) -> Token:
    """Split a token as rmw_zenoh's graph cache does (`Entity::make(keyexpr)`); ValueError if it would
    refuse it: the wrong admin space, an unknown kind, an empty part, too few parts for its kind."""
    parts = key.split("/")
    if len(parts) < 9 or parts[0] != ADMIN_SPACE or any(not p for p in parts):
        raise ValueError(f"not an rmw_zenoh liveliness token: {key!r}")
    kind = parts[5]
    if kind not in (NODE, PUBLISHER, SUBSCRIPTION, "SS", "SC"):
        raise ValueError(f"unknown entity kind {kind!r} in {key!r}")
    head = Token(
        int(parts[1]), parts[2], parts[3], parts[4], kind, demangle(parts[6]), demangle(parts[7]),
        demangle(parts[8]),
    )  # fmt: skip
    if kind == NODE:
        if len(parts) != 9:
            raise ValueError(f"a node token has 9 parts: {key!r}")
        return head
    if len(parts) != 13:
        raise ValueError(f"an entity token has 13 parts: {key!r}")
    return replace(head, topic=demangle(parts[9]), dds_type=parts[10], type_hash=parts[11], qos=parts[12])


def entity_gid(token: str) -> bytes:
    """The 16-byte GID rmw_zenoh gives the entity of this token: XXH3-128 of the key, low half first."""
    import xxhash  # the ros2 extra; imported here so the rest of this module needs nothing

    return int(xxhash.xxh3_128_intdigest(token.encode())).to_bytes(GID_SIZE, "little")


def attachment(sequence_number: int, source_timestamp_ns: int, gid: bytes) -> bytes:
    """A sample's attachment (the module docstring gives the layout)."""
    return ATTACHMENT.pack(sequence_number, source_timestamp_ns, GID_SIZE, gid)


def parse_attachment(data: bytes) -> tuple[int, int, bytes]:
    """(sequence number, source timestamp ns, GID) of an attachment; ValueError when it is not one."""
    if len(data) != ATTACHMENT.size:
        raise ValueError(f"an rmw_zenoh attachment is {ATTACHMENT.size} bytes, got {len(data)}")
    seq, stamp, n, gid = ATTACHMENT.unpack(data)
    if n != GID_SIZE:
        raise ValueError(f"GID length {n}, expected {GID_SIZE}")
    return seq, stamp, gid
