"""ROS 2 on Cyclone DDS without ROS: names, QoS, and services laid out as rmw_cyclonedds_cpp does.

- A ROS 2 topic ``/ns/name`` is the DDS topic ``rt/ns/name``; a service ``/ns/srv`` is the pair
  ``rq/ns/srvRequest`` (client → service) and ``rr/ns/srvReply`` (service → client).
- QoS: ROS 2's default profile as rmw_cyclonedds_cpp maps it: reliable, volatile, keep last 10,
  automatic liveliness, no autodispose of unregistered instances (services use the same profile).
- Service samples start with rmw_cyclonedds_cpp's request header (``guid``: the client's request
  writer's instance handle, ``seq``: the request's number); a service copies both into its reply,
  and each endpoint's USER_DATA says ``clientid=...;`` or ``serviceid=...;`` so that a service can
  tell when a client's reply reader has been matched. The layout and its source: ``docs/ros2.md``.

Whom a participant talks to (:func:`discovery`) follows ROS 2's own settings, configured as
rmw_cyclonedds_cpp configures a ROS 2 node (:func:`ros2_config`), except that akarm's default is
``LOCALHOST`` where ROS 2's is ``SUBNET`` (and that it keeps pinging this machine, see
:func:`discovery`): ``ROS_AUTOMATIC_DISCOVERY_RANGE`` (``LOCALHOST``, the
default here: every node on this machine, whatever its range, and another machine only if it names
this one as a static peer; ``SUBNET``: the network, by multicast; ``OFF``; ``SYSTEM_DEFAULT``:
Cyclone's own defaults), ``ROS_STATIC_PEERS`` (``host;host``: these too), the older
``ROS_LOCALHOST_ONLY=1``, ``akarm serve --ros-network`` (``SUBNET``) and ``--ros-loopback`` (the
loopback interface alone, :data:`LOOPBACK_CONFIG`: no other machine, even by name). A
``CYCLONEDDS_URI`` of the user's own replaces all of it but ``--ros-loopback``: Cyclone DDS then reads
that configuration alone.
"""

from __future__ import annotations

import itertools
import os
import re
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, cast

from cyclonedds._clayer import ddspy_take  # type: ignore[import-not-found]  # the binding's C layer: no stubs
from cyclonedds.core import DDSException, InstanceState, ReadCondition, SampleState, ViewState
from cyclonedds.domain import Domain, DomainParticipant
from cyclonedds.pub import DataWriter
from cyclonedds.qos import Policy, Qos
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from cyclonedds.util import duration

from akarm.control.loop import collector_paused
from akarm.errors import AkarmError, ArgumentError
from akarm.ros import msgs

__all__ = [
    "LOOPBACK",
    "LOOPBACK_CONFIG",
    "RANGES",
    "Discovery",
    "Node",
    "RawSample",
    "ServiceServer",
    "TriggerClient",
    "TriggerServer",
    "decode",
    "discovery",
    "latched_qos",
    "qos",
    "ros2_config",
    "ros_name",
    "sample_info",
    "sender",
    "service_topics",
    "take_raw",
    "topic_name",
]

#: ROS 2's discovery ranges (``ROS_AUTOMATIC_DISCOVERY_RANGE``), as rcl spells them
RANGES = ("LOCALHOST", "SUBNET", "OFF", "SYSTEM_DEFAULT")
_PEER = re.compile(r"^[A-Za-z0-9_.:%\[\]-]{1,253}$")  # a host name or an IPv4/IPv6 address, nothing else
_MAX_AUTO_INDEX = 60  # participants the loopback configuration can hold in unicast discovery
_ROS2_MAX_AUTO_INDEX = 32  # rmw_cyclonedds_cpp's MaxAutoParticipantIndex: the ports a node pings on a host
#: the range of ``--ros-loopback`` (:data:`LOOPBACK_CONFIG`), not one of ROS 2's
LOOPBACK = "LOOPBACK"


@dataclass(frozen=True)
class Discovery:
    """Whom a DDS participant talks to, and the Cyclone DDS configuration that says so.

    Attributes:
        range: ``"LOCALHOST"`` (ROS 2's: every participant on this machine, and hosts that name this
            one as a static peer), ``"LOOPBACK"`` (the loopback interface alone: participants on this
            machine that look for it on the loopback interface), ``"SUBNET"`` (the network, by
            multicast), ``"OFF"`` (no other participant, not even on this machine), ``"SYSTEM_DEFAULT"``
            (Cyclone DDS's own defaults), or ``"CYCLONEDDS_URI"`` (the user's own configuration, which
            decides it all).
        peers: the static peers (``ROS_STATIC_PEERS``), looked for in addition.
        config: the Cyclone DDS XML to create the domain with; ``None``: Cyclone's own
            (``CYCLONEDDS_URI``, else its defaults).
        source: what chose it (``"default"``, ``"--ros-network"``, the variable and its value).
        warnings: what in the environment was not understood, and ignored.
    """

    range: str
    peers: tuple[str, ...] = ()
    config: str | None = None
    source: str = "default"
    warnings: tuple[str, ...] = ()

    @property
    def network(self) -> bool:
        """True when participants on other machines may reach it uninvited (or the user's configuration
        decides): ``LOCALHOST`` without peers answers only hosts that name this one."""
        return self.range in ("SUBNET", "SYSTEM_DEFAULT", "CYCLONEDDS_URI") or bool(self.peers)

    def describe(self) -> str:
        """One line for the server's output: who can reach the node."""
        peers = f" and the static peers {', '.join(self.peers)}" if self.peers else ""
        text = {
            "LOCALHOST": "this machine (any ROS 2 discovery range; another host only as a static peer)" + peers,
            LOOPBACK: "this machine only (loopback)",
            "SUBNET": "the network (multicast discovery)" + peers,
            "OFF": "no one (discovery off)",
            "SYSTEM_DEFAULT": "whoever Cyclone DDS's defaults reach (the network)",
            "CYCLONEDDS_URI": "as CYCLONEDDS_URI configures Cyclone DDS",
        }[self.range]
        return f"{text}; {self.source}"


def _fragment(general: str = "", discovery: str = "") -> str:
    return (f'<CycloneDDS><Domain Id="any"><General>{general}</General><Discovery>{discovery}</Discovery>'
            "</Domain></CycloneDDS>")


def _peers_xml(peers: tuple[str, ...]) -> str:
    return "<Peers>" + "".join(f'<Peer address="{p}"/>' for p in peers) + "</Peers>" if peers else ""


_AUTO_INDEX = ("<ParticipantIndex>auto</ParticipantIndex>"
               f"<MaxAutoParticipantIndex>{_MAX_AUTO_INDEX}</MaxAutoParticipantIndex>")
_NO_MULTICAST = "<AllowMulticast>false</AllowMulticast>"


#: Cyclone DDS configuration that keeps discovery and data on the loopback interface (no multicast,
#: unicast discovery of the participants on 127.0.0.1): ``akarm serve --ros-loopback``, spelt out for
#: other programs: ``export CYCLONEDDS_URI='<the string>'``. Participants configured so, and ROS 2 nodes
#: at ``LOCALHOST`` on this machine, reach it; nothing else.
LOOPBACK_CONFIG = _fragment(f'<Interfaces><NetworkInterface address="127.0.0.1"/></Interfaces>{_NO_MULTICAST}',
                            _AUTO_INDEX + _peers_xml(("127.0.0.1",)))


def ros2_config(rng: str, peers: tuple[str, ...] = ()) -> str | None:
    """The Cyclone DDS configuration rmw_cyclonedds_cpp (Iron and later: ``check_create_domain`` in
    ``rmw_node.cpp``) gives a ROS 2 node of discovery range ``rng`` with static ``peers``; ``None``:
    none (``SYSTEM_DEFAULT``: Cyclone's own defaults). ``LOOPBACK`` is akarm's own (:data:`LOOPBACK_CONFIG`).

    - ``SUBNET``: multicast (Cyclone's default) and participant index ``auto`` (at most 32), plus the
      peers: the index gives the node a well-known unicast port, where a ``LOCALHOST`` node on the same
      host finds it.
    - ``LOCALHOST``: no multicast, participant index ``auto`` (at most 32), the peers ``localhost``
      and ``peers``, on the default network interface.
    - ``OFF``: no multicast, participant index ``none`` and a tag of this process's own.
    """
    auto = ("<ParticipantIndex>auto</ParticipantIndex>"
            f"<MaxAutoParticipantIndex>{_ROS2_MAX_AUTO_INDEX}</MaxAutoParticipantIndex>")
    if rng == LOOPBACK:
        return LOOPBACK_CONFIG
    if rng == "LOCALHOST":
        return _fragment(_NO_MULTICAST, auto + _peers_xml(("localhost", *peers)))
    if rng == "SUBNET":
        return _fragment(discovery=auto + _peers_xml(peers))
    if rng == "OFF":
        return _fragment(_NO_MULTICAST, f"<ParticipantIndex>none</ParticipantIndex><Tag>akarm_discovery_off_"
                                        f"{os.getpid()}</Tag>")
    return None


#: what the server adds to ROS 2's LOCALHOST: ping this host's participant ports every second for
#: good. rmw_cyclonedds_cpp's fragment alone pings them at start and stops after 30 s (Cyclone's
#: InitialLocatorPruneDelay); a SUBNET node, which pings no one but answers a ping, started on this
#: machine after that never found the server (tried: not in 38 s).
_KEEP_PINGING = "<InitialLocatorPruneDelay>inf</InitialLocatorPruneDelay><SPDPInterval>1 s</SPDPInterval>"


def _server_config(rng: str, peers: tuple[str, ...]) -> str | None:
    """The server's Cyclone DDS configuration of range ``rng``: :func:`ros2_config`'s, and for
    ``LOCALHOST`` pings of this machine that go on (:data:`_KEEP_PINGING`)."""
    config = ros2_config(rng, peers)
    if rng == "LOCALHOST" and config is not None:
        config = config.replace("</Discovery>", _KEEP_PINGING + "</Discovery>")
    return config


def _range(env: Mapping[str, str], network: bool, warnings: list[str]) -> tuple[str, str, bool]:
    """The discovery range, what chose it, and whether static peers apply."""
    wanted = env.get("ROS_AUTOMATIC_DISCOVERY_RANGE", "").strip()
    if network:
        return "SUBNET", "--ros-network", True
    if env.get("ROS_LOCALHOST_ONLY", "").strip() == "1":
        return "LOCALHOST", "ROS_LOCALHOST_ONLY=1", False
    if wanted in RANGES:
        return wanted, f"ROS_AUTOMATIC_DISCOVERY_RANGE={wanted}", wanted in ("LOCALHOST", "SUBNET")
    if wanted:
        warnings.append(f"ROS_AUTOMATIC_DISCOVERY_RANGE={wanted[:40]!r} is not one of {', '.join(RANGES)}; "
                        "using LOCALHOST")
    return "LOCALHOST", "default (--ros-loopback closes it to the loopback interface; --ros-network or " \
                        "ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET opens it)", True


def discovery(env: Mapping[str, str] | None = None, network: bool = False, loopback: bool = False) -> Discovery:
    """Whom the server's participant talks to, from ROS 2's environment variables in ``env`` (default
    ``os.environ``), ``network`` (``akarm serve --ros-network``) and ``loopback`` (``--ros-loopback``),
    configured as rmw_cyclonedds_cpp configures a ROS 2 node (:func:`ros2_config`), but for the
    default: ``LOCALHOST``, not ROS 2's ``SUBNET``, and at ``LOCALHOST`` the server keeps pinging this
    machine's participant ports every second (rmw's stops after 30 s), so that a ROS 2 node of any
    range started on this machine later finds it (within a second).

    Precedence: ``loopback`` (the loopback interface alone, whatever else is set: a ``CYCLONEDDS_URI``
    too, said in :attr:`Discovery.warnings`); a ``CYCLONEDDS_URI`` of the user's own (Cyclone reads
    it, alone); ``network`` (``SUBNET``); ``ROS_LOCALHOST_ONLY=1`` (``LOCALHOST``, peers ignored, as
    ROS 2 does); ``ROS_AUTOMATIC_DISCOVERY_RANGE``; else ``LOCALHOST``. ``ROS_STATIC_PEERS``
    (``;``-separated host names or addresses) adds peers to ``LOCALHOST`` and ``SUBNET``.

    Raises:
        ArgumentError: both ``network`` and ``loopback``.
    """
    env = os.environ if env is None else env
    if network and loopback:
        raise ArgumentError("--ros-network and --ros-loopback contradict each other",
                            fix="give one of them (neither: this machine, as ROS 2's LOCALHOST)")
    if loopback:
        ignored = [k for k in ("CYCLONEDDS_URI", "ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_STATIC_PEERS",
                               "ROS_LOCALHOST_ONLY") if env.get(k, "").strip()]
        notes = (f"{', '.join(ignored)} ignored with --ros-loopback",) if ignored else ()
        return Discovery(LOOPBACK, (), LOOPBACK_CONFIG, "--ros-loopback", notes)
    if env.get("CYCLONEDDS_URI", "").strip():
        return Discovery("CYCLONEDDS_URI", source="CYCLONEDDS_URI is set")
    warnings: list[str] = []
    peers: list[str] = []
    for p in (x.strip() for x in env.get("ROS_STATIC_PEERS", "").split(";")):
        if p and _PEER.match(p):
            peers.append(p)
        elif p:
            warnings.append(f"ROS_STATIC_PEERS: {p[:60]!r} is not a host name or address; ignored")
    rng, source, with_peers = _range(env, network, warnings)
    if peers and not with_peers:
        warnings.append(f"ROS_STATIC_PEERS is ignored with {source}")
        peers = []
    return Discovery(rng, tuple(peers), _server_config(rng, tuple(peers)), source, tuple(warnings))


_domains: dict[int, tuple[Domain, str]] = {}  # the domains this process created with a configuration: kept
_domains_lock = threading.Lock()


def _open_domain(domain: int, config: str) -> str | None:
    """Create DDS domain ``domain`` with ``config`` in this process (once: a domain's configuration is
    fixed when it is made); a note when it existed already with another configuration, which then applies."""
    with _domains_lock:
        made = _domains.get(domain)
        if made is not None:
            return None if made[1] == config else "this process's DDS domain was made with another configuration"
        try:
            _domains[domain] = (Domain(domain, config), config)  # kept for the process's life: deleting a domain
        except DDSException:  # deletes every participant in it, others' too
            return "this process had made its DDS domain already, with Cyclone DDS's own configuration"
        return None


_TOKEN = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
ANY = SampleState.Any | ViewState.Any | InstanceState.Any


def ros_name(namespace: str, name: str) -> str:
    """The fully qualified ROS 2 name of ``name`` in ``namespace``: ``("arm1", "joint_states")`` →
    ``/arm1/joint_states``. Raises :class:`~akarm.AkarmError` for a name ROS 2 would refuse."""
    parts = [p for p in f"{namespace}/{name}".split("/") if p]
    for p in parts:
        if not _TOKEN.match(p):
            raise AkarmError(f"{namespace!r}/{name!r} is not a valid ROS 2 name ({p!r})",
                             fix="use letters, digits and underscores, not starting with a digit, separated by /")
    return "/" + "/".join(parts)


def topic_name(namespace: str, name: str) -> str:
    """The DDS topic of ROS 2 topic ``name`` in ``namespace``: ``rt/arm1/joint_states``."""
    return "rt" + ros_name(namespace, name)


def service_topics(namespace: str, name: str) -> tuple[str, str]:
    """The DDS topics of ROS 2 service ``name``: ``(rq/NS/nameRequest, rr/NS/nameReply)``."""
    full = ros_name(namespace, name)
    return f"rq{full}Request", f"rr{full}Reply"


def qos(depth: int = 10, user_data: bytes | None = None) -> Qos:
    """ROS 2's default QoS profile (reliable, volatile, keep last ``depth``) as rmw_cyclonedds_cpp sets it."""
    policies = [Policy.Reliability.Reliable(max_blocking_time=duration(milliseconds=100)),
                Policy.Durability.Volatile, Policy.History.KeepLast(depth),
                Policy.Liveliness.Automatic(lease_duration=duration(infinite=True)),
                Policy.WriterDataLifecycle(autodispose=False)]
    if user_data is not None:
        policies.append(Policy.Userdata(data=user_data))
    return Qos(*policies)


def latched_qos() -> Qos:
    """Reliable, transient local, keep last 1: a late reader gets the last sample (an action's status,
    ``ros_discovery_info``), with the durability service history rmw_cyclonedds_cpp sets for it."""
    return Qos(Policy.Reliability.Reliable(max_blocking_time=duration(milliseconds=100)),
               Policy.Durability.TransientLocal, Policy.History.KeepLast(1),
               Policy.DurabilityService(cleanup_delay=0, history=Policy.History.KeepLast(1), max_samples=-1,
                                        max_instances=-1, max_samples_per_instance=-1),
               Policy.Liveliness.Automatic(lease_duration=duration(infinite=True)),
               Policy.WriterDataLifecycle(autodispose=False))


def sample_info(sample: object) -> Any:
    """The DDS sample info cyclonedds attaches to a sample it delivers."""
    return cast(Any, sample).sample_info


@dataclass(frozen=True)
class RawSample:
    """A sample taken from a reader and not decoded yet: its CDR bytes (the 4-byte encapsulation first)
    and its DDS sample info (:func:`sender` takes it as it takes a decoded sample)."""

    data: bytes
    sample_info: Any


def take_raw(reader: DataReader, n: int = 16) -> list[RawSample]:
    """Up to ``n`` samples of ``reader``, taken (they no longer trigger its conditions) and not decoded:
    a sample's size can be checked before the pure-Python decoder spends time and objects on it (24 MB
    of a million points took it 12 s). Samples without data (a writer gone) are left out."""
    got = ddspy_take(reader._ref, ANY, n)  # private-ok: the binding's own handle of the reader
    if isinstance(got, int):
        raise DDSException(got, f"Occurred while taking data in {reader!r}")
    return [RawSample(bytes(data), info) for data, info in got or () if info.valid_data]


def decode(data_type: Any, raw: RawSample) -> Any:
    """``raw``'s message, of ``data_type`` (its sample info attached, as the binding's own take does),
    decoded with the garbage collector paused: a collection while the decoder makes its objects would
    scan them all again and again, holding the interpreter lock (0.5 s pauses stopped the control loop).

    Raises:
        ArgumentError: the sample does not decode (a string that is not UTF-8, bytes cut short): one
            sample's fault, which leaves the others taken with it as they are.
    """
    try:
        with collector_paused():
            msg = data_type.deserialize(raw.data)
    except Exception as e:  # the binding's decoder: UnicodeDecodeError, struct.error, IndexError, ...
        raise ArgumentError(f"a {data_type.__name__} of {len(raw.data)} bytes that does not decode "
                            f"({type(e).__name__}: {str(e)[:200]})",
                            fix="send well-formed CDR of the message's ROS 2 type (strings in UTF-8)") from None
    msg.sample_info = raw.sample_info
    return msg


def sender(reader: DataReader, sample: object) -> str:
    """Who wrote ``sample`` (taken from ``reader``): ``participant GUID``, the DDS participant of the
    writer (as ``ros2 doctor`` and Cyclone DDS's traces name it), or ``"an unknown participant"``
    when it has gone meanwhile."""
    try:
        wr = reader.get_matched_publication_data(sample_info(sample).publication_handle)
    except Exception:  # gone, or the binding refused the handle
        wr = None
    key = getattr(wr, "participant_key", None)
    return f"participant {key}" if key is not None else "an unknown participant"


def _user_data_key(q: Qos | None, key: str) -> str | None:
    """``value`` of ``key=value;`` in an endpoint's USER_DATA (as rmw_cyclonedds_cpp writes it)."""
    if q is None:
        return None
    try:
        data = q[Policy.Userdata].data
    except (KeyError, AttributeError):
        return None
    for item in bytes(data).decode("utf-8", "replace").split(";"):
        k, sep, v = item.partition("=")
        if sep and k == key:
            return v
    return None


class Node:
    """One DDS participant in ``domain`` with ROS 2 naming under ``namespace``.

    Its USER_DATA says ``enclave=/;`` as rmw_cyclonedds_cpp's participants do (ROS 2's graph keeps
    the participants that say it). :attr:`endpoints` are the readers and writers opened through it,
    for ``ros_discovery_info`` (:mod:`akarm.ros.graph`).

    ``reach``: whom it talks to (:func:`discovery`); ``None``: Cyclone DDS's own configuration
    (``CYCLONEDDS_URI``, else its defaults). :attr:`note` says when the process had already made the
    domain with another configuration (the first one made applies to every participant in it).
    """

    def __init__(self, domain: int = 0, namespace: str = "", reach: Discovery | None = None) -> None:
        if not 0 <= domain <= 232:
            raise AkarmError(f"DDS domain {domain} is out of range",
                             fix="use a domain ID from 0 to 232 (ROS_DOMAIN_ID)")
        self.domain = domain
        self.namespace = namespace.strip("/")
        ros_name(self.namespace, "x")  # validates the namespace
        self.reach = reach
        self.note = _open_domain(domain, reach.config) if reach is not None and reach.config is not None else None
        self.participant = DomainParticipant(domain, qos=Qos(Policy.Userdata(data=b"enclave=/;")))
        self.endpoints: list[DataReader | DataWriter] = []
        self._closed = False
        self._ids = itertools.count(1)
        self._prefix = self.participant.get_guid().bytes[:12]

    def unique_id(self, kind: str) -> bytes:
        """USER_DATA ``clientid=...;`` / ``serviceid=...;``: the participant's GUID prefix and a counter,
        printed as rmw_cyclonedds_cpp prints it (hex bytes separated by dots)."""
        raw = self._prefix + next(self._ids).to_bytes(4, "big")
        return f"{kind}={raw[0]:02x}{''.join(f'.{b:x}' for b in raw[1:])};".encode()

    def topic(self, name: str, data_type: Any, ros: bool = True) -> Topic:
        """The DDS topic of ROS 2 topic ``name`` (or of the raw DDS topic ``name`` with ``ros=False``)."""
        return Topic(self.participant, topic_name(self.namespace, name) if ros else name, data_type, qos=qos())

    def publisher(self, name: str, data_type: Any, q: Qos | None = None) -> DataWriter:
        return self.writer(topic_name(self.namespace, name), data_type, q or qos())

    def subscription(self, name: str, data_type: Any, depth: int = 10) -> DataReader:
        return self.reader(topic_name(self.namespace, name), data_type, qos(depth))

    def writer(self, dds_topic: str, data_type: Any, q: Qos) -> DataWriter:
        """A writer on the DDS topic ``dds_topic`` (listed in :attr:`endpoints`)."""
        w = DataWriter(self.participant, Topic(self.participant, dds_topic, data_type, qos=qos()), qos=q)
        self.endpoints.append(w)
        return w

    def reader(self, dds_topic: str, data_type: Any, q: Qos) -> DataReader:
        """A reader of the DDS topic ``dds_topic`` (listed in :attr:`endpoints`)."""
        r = DataReader(self.participant, Topic(self.participant, dds_topic, data_type, qos=qos()), qos=q)
        self.endpoints.append(r)
        return r

    def close(self) -> None:
        """Delete the participant and everything in it (other participants see it leave at once)."""
        if not self._closed:
            self._closed = True
            self.participant.__del__()  # explicit: left to the garbage collector, a ghost stays for a lease


class ServiceServer:
    """The service side of ROS 2 service ``name`` with request and response types of
    :mod:`akarm.ros.msgs` (their first fields: the request header), as rmw_cyclonedds_cpp lays it out.

    :meth:`take` the requests when :attr:`condition` triggers a WaitSet, and :meth:`reply` to each.
    """

    def __init__(self, node: Node, name: str, request_type: Any, response_type: Any,
                 bad: Callable[[str], None] | None = None) -> None:
        self.name = ros_name(node.namespace, name)
        self.bad = bad  # told of each request dropped because it does not decode (with who sent it)
        self.dropped = 0
        rq, rr = service_topics(node.namespace, name)
        q = qos(user_data=node.unique_id("serviceid"))
        self._type = request_type
        self._reader = node.reader(rq, request_type, q)
        self._writer = node.writer(rr, response_type, q)
        self.condition = ReadCondition(self._reader, ANY)

    def client_ready(self, request_writer: int) -> str:
        """``yes`` when the requesting client's reply reader is matched, ``maybe``, or ``gone``
        (rmw_cyclonedds_cpp's check_for_response_reader)."""
        wr = self._reader.get_matched_publication_data(request_writer)
        if wr is None:
            return "gone"
        cid = _user_data_key(wr.qos, "clientid")
        if cid is None:
            return "yes"  # a client that does not say who it is: assume its reader is there
        for h in self._writer.get_matched_subscriptions():
            rd = self._writer.get_matched_subscription_data(h)
            if rd is not None and _user_data_key(rd.qos, "clientid") == cid:
                return "yes"
        return "maybe"

    def caller(self, req: Any) -> str:
        """Who sent ``req``: its participant's GUID (see :func:`sender`)."""
        return sender(self._reader, req)

    def take_raw(self) -> list[RawSample]:
        """The requests waiting, not decoded yet (taken: they no longer trigger :attr:`condition`)."""
        return take_raw(self._reader, 16)

    def decode(self, raw: RawSample) -> Any:
        """A request taken by :meth:`take_raw`, decoded (see :func:`decode`)."""
        return decode(self._type, raw)

    def take(self) -> list[Any]:
        """The requests waiting, decoded (taken: they no longer trigger :attr:`condition`). One that does
        not decode is dropped alone (counted in :attr:`dropped`, told to ``bad``); the others are kept."""
        taken = []
        for raw in self.take_raw():
            try:
                taken.append(self.decode(raw))
            except ArgumentError as e:
                self.drop(raw, e)
        return taken

    def drop(self, raw: RawSample, e: AkarmError) -> None:
        """Count a request that is not answered, and tell ``bad`` why and who sent it."""
        self.dropped += 1
        if self.bad is not None:
            self.bad(f"{self.name}: a request from {self.caller(raw)} dropped: {e}")

    def reply(self, request: Any, response: Any, wait: float = 0.1) -> str:
        """Send ``response`` (its ``guid`` and ``seq`` are set from ``request``'s) to the client that sent
        ``request``, once its reply reader is matched: waits up to ``wait`` s for that (as
        rmw_cyclonedds_cpp, 100 ms). ``yes`` when sent; ``maybe`` or ``gone`` when not (not yet, never)."""
        response.guid, response.seq = request.guid, request.seq
        handle = sample_info(request).publication_handle
        end = time.monotonic() + wait
        state = self.client_ready(handle)
        while state == "maybe" and time.monotonic() < end:
            time.sleep(0.005)
            state = self.client_ready(handle)
        if state == "yes":
            self._writer.write(response)
        return state


class TriggerServer(ServiceServer):
    """A ``std_srvs/Trigger`` service, answered by ``handler() -> (success, message)``.

    Call :meth:`poll` (e.g. when :attr:`condition` triggers a WaitSet) to answer waiting requests.
    """

    def __init__(self, node: Node, name: str, handler: Callable[[], tuple[bool, str]],
                 bad: Callable[[str], None] | None = None) -> None:
        super().__init__(node, name, msgs.TriggerRequest, msgs.TriggerResponse, bad)
        self.handler = handler

    def answer(self, req: msgs.TriggerRequest) -> bool:
        """Run the handler for ``req`` and reply (to the client that asked); False if it has gone."""
        try:
            ok, text = self.handler()
        except AkarmError as e:
            ok, text = False, str(e)
        return self.reply(req, msgs.TriggerResponse(0, 0, bool(ok), text)) == "yes"

    def poll(self) -> int:
        """Answer every waiting request, one after the other; returns how many were answered."""
        return sum(self.answer(req) for req in self.take())


class TriggerClient:
    """Calls a ``std_srvs/Trigger`` service as an rmw_cyclonedds_cpp client does."""

    def __init__(self, node: Node, name: str) -> None:
        rq, rr = service_topics(node.namespace, name)
        q = qos(user_data=node.unique_id("clientid"))
        self._writer = DataWriter(node.participant, Topic(node.participant, rq, msgs.TriggerRequest, qos=qos()), qos=q)
        self._reader = DataReader(node.participant, Topic(node.participant, rr, msgs.TriggerResponse, qos=qos()), qos=q)
        self._guid = self._writer.get_instance_handle() & 0xFFFF_FFFF_FFFF_FFFF  # the binding gives it signed
        self._seq = 0
        self.name = name

    def ready(self) -> bool:
        """True once the service's request reader and reply writer are both matched."""
        return bool(self._writer.get_matched_subscriptions()) and bool(self._reader.get_matched_publications())

    def call(self, timeout: float = 5.0) -> msgs.TriggerResponse:
        """Send a request and wait for its reply.

        Raises:
            AkarmError: no service answered within ``timeout`` s.
        """
        end = time.monotonic() + timeout
        while not self.ready():
            if time.monotonic() > end:
                raise AkarmError(f"no service {self.name!r} found", fix="is akarm serve running, in this domain "
                                 "and namespace, and can Cyclone DDS reach it (CYCLONEDDS_URI)?")
            time.sleep(0.01)
        self._seq += 1
        self._writer.write(msgs.TriggerRequest(self._guid, self._seq, 0))
        while time.monotonic() < end:
            for rep in self._reader.take(16):
                if sample_info(rep).valid_data and rep.guid == self._guid and rep.seq == self._seq:
                    return rep
            time.sleep(0.002)
        raise AkarmError(f"service {self.name!r} did not answer within {timeout:g} s")
