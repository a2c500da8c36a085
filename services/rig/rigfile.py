"""Rig files (docs/rig-format.md): which channels exist, where every service listens."""

from __future__ import annotations

import math
import tomllib
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

from .frame import MAX_CHANNEL_PIXELS, ChannelSpec
from .options import RenderOptions

#: How the host paces its frames (the ``[sync]`` table's ``pace``): name -> what it means, for
#: --help and the rig file's errors (docs/frame-lock.md).
PACES = {
    "ticks": "a fixed rate: frame k at the k-th tick of --rate, simulation time k / rate (replays "
             "and tests that need exact simulation times)",
    "acks": "paced by the rig: the next frame as soon as every channel acknowledged the previous one, "
            "at most --rate a second; simulation time is the wall clock's, so the flight flies in real "
            "time and an input waits at most for the frame in flight",
}

#: Channels a rig may have: the swap barrier and the compositor's bounds scale with it, and
#: no projection dome uses more.
MAX_CHANNELS = 64


class RigError(ValueError):
    """A rig file that cannot be used; the message names the file, the key and the value."""


@dataclass(frozen=True)
class SyncSpec:
    """The swap barrier and what the compositor may hold (the ``[sync]`` table; docs/rig-format.md).

    Attributes:
        frame_timeout_s: the host's wait per frame for every present channel's acknowledgement
            (the swap barrier); a channel later than this is counted late and the frame goes on.
        pending_timeout_s: a frame still missing images this long after it opened in the
            compositor is finalised as incomplete, naming the missing channels.
        max_pending_frames: frames the compositor holds open at once; opening one more
            finalises the oldest as incomplete.
        max_pending_mib: pixels those frames may hold, MiB; the same when exceeded.
        pace: how the host paces its frames, a name of PACES.
    """

    frame_timeout_s: float = 5.0
    pending_timeout_s: float = 10.0
    max_pending_frames: int = 16
    max_pending_mib: float = 512.0
    pace: str = "ticks"


#: Pixel formats between worker and compositor (the ``wire`` key): display-ready sRGB bytes
#: (what a display and the PNGs show), or linear half floats (for accurate EXR recording).
WIRE_FORMATS = ("srgb8", "half")


@dataclass(frozen=True)
class WireSpec:
    """How channel images travel from the workers to the compositor (the ``[compositor]``
    table's ``wire`` and ``shared_memory`` keys; docs/rig-format.md).

    Attributes:
        format: "srgb8" (RGB bytes, sRGB-encoded as the PNGs are) or "half" (linear half floats).
        shared_memory: a worker on the compositor's machine hands its pixels over in shared
            memory (services/rig/shared_images.py), falling back to sending them inline.
    """

    format: str = "srgb8"
    shared_memory: bool = True


def check_wire_format(value: object, where: str) -> str:
    """value if it is a wire format.

    Raises:
        ValueError: it is not; the message names where and the value.
    """
    if value not in WIRE_FORMATS:
        raise ValueError(f"{where}: {value!r} is not one of {_one_of(WIRE_FORMATS)}")
    return str(value)


def _one_of(names: tuple[str, ...]) -> str:
    return ", ".join(repr(n) for n in names)


@dataclass(frozen=True)
class BlendSpec:
    """Edge blending between adjacent channels (the ``[blend]`` table; docs/edge-blending.md).

    Attributes:
        overlap_deg: the angle adjacent channels are meant to share (0: abutting); the seam
            check measures every seam against it.
        power: exponent of the blend ramp's two halves (1: linear cross-fade).
        gamma: the projectors' gamma: a mask sent to a projector is the linear-light ramp to
            the power 1 / gamma.
        tolerance_deg: a seam whose angular error exceeds this is reported as misaligned.
    """

    overlap_deg: float = 0.0
    power: float = 2.0
    gamma: float = 2.2
    tolerance_deg: float = 0.05


@dataclass(frozen=True)
class TlsSpec:
    """Mutual TLS between the rig's services (the ``[tls]`` table; docs/security.md).

    Paths are absolute (a relative path in the file is taken from the rig file's directory).

    Attributes:
        ca: PEM file of the certificate authority every peer's certificate must chain to.
        cert: PEM file of this machine's certificate (server and client).
        key: PEM file of its private key.
        allow_plaintext: let services without TLS listen on, or connect to, addresses other
            than the loopback (refused by default: plaintext belongs on one machine).
    """

    ca: str = ""
    cert: str = ""
    key: str = ""
    allow_plaintext: bool = False

    @property
    def enabled(self) -> bool:
        return bool(self.cert)


@dataclass(frozen=True)
class CigiSpec:
    """The rig as a CIGI image generator (the ``[cigi]`` table; docs/cigi.md).

    Attributes:
        listen: host:port of the UDP socket the host's datagrams arrive at.
        host_port: UDP port on the host's machine the replies go to (its sender address).
        origin: WGS-84 latitude, longitude (degrees) and height (metres) of the world's
            (0, 0, 0): the database origin geodetic positions are converted around.
        query_channel: the channel whose worker answers height-of-terrain and line-of-sight
            queries (it holds the databases); "" takes the first channel.
        mode: "sync" (the IG is the clock: one Start of Frame per frame, the host answers each)
            or "async" (the host sends at its own rate; eyepoints extrapolated by timestamp).
        stale_after_s: the host is reported stale after this long without a message.
        query_timeout_s: deadline of a query RPC to the query channel's worker.
        host: IP address of the host's machine, to send Start of Frame to before the host's
            first message (hosts that wait for the IG to speak first, as the CIGI Class
            Library's MiniHost does); "": wait for the host.
        configured: the rig file has a ``[cigi]`` table: the rig is meant to follow a CIGI
            host, so `ig compile` and the workers' warm-up prepare the query kernels (a rig
            without one pays for them only if a query ever comes).
        initial_pose: WGS-84 latitude, longitude (degrees), height (metres), heading, pitch,
            roll (degrees) of the eyepoint rendered until the host's first ownship message
            (and after a restart or reset has forgotten it); None: start_pose's default.
    """

    listen: str = "127.0.0.1:8000"
    host_port: int = 8001
    #: The bundled airfield's (channel_worker AIRFIELD_ORIGIN; a test keeps them equal).
    origin: tuple[float, float, float] = (36.6089, -84.1708, 349.2)
    query_channel: str = ""
    mode: str = "sync"
    stale_after_s: float = 1.0
    query_timeout_s: float = 0.5
    host: str = ""
    configured: bool = False
    initial_pose: tuple[float, float, float, float, float, float] | None = None

    @property
    def start_pose(self) -> tuple[float, float, float, float, float, float]:
        """The pose rendered before the first ownship message: initial_pose, or
        DEFAULT_INITIAL_HEIGHT_M above the origin looking north, level."""
        if self.initial_pose is not None:
            return self.initial_pose
        lat, lon, h = self.origin
        return (lat, lon, h + DEFAULT_INITIAL_HEIGHT_M, 0.0, 0.0, 0.0)


#: Height of the default initial pose above cigi.origin, metres: the height `ig cigi-host`'s
#: built-in script flies at, high enough to see the ground around the origin rather than
#: the inside of a hill, low enough to see it in detail.
DEFAULT_INITIAL_HEIGHT_M = 300.0


#: How the host follows another simulator's pose stream between its datagrams (the ``[simhost]``
#: table's ``timing``): name -> what it means, for --help and the rig file's errors
#: (docs/sim-hosts.md).
SIMHOST_TIMINGS = {
    "interpolate": "show the pose a fixed delay behind the newest datagram, interpolated between the two "
                   "around it (smooth under jitter; the delay is added to the latency)",
    "extrapolate": "show the pose now, extrapolated from the last two datagrams up to max_extrapolate_s "
                   "(no added delay; overshoots when the aircraft changes its motion)",
}


@dataclass(frozen=True)
class SimHostSpec:
    """Another simulator's pose stream as the eyepoint (the ``[simhost]`` table; docs/sim-hosts.md).

    Attributes:
        url: what `ig host --simhost` without a URL follows (fgfs://, fgfs-generic://,
            xplane://); "": the flag needs one.
        origin: WGS-84 latitude, longitude (degrees) and height (metres) of the world's
            (0, 0, 0); None takes ``cigi.origin`` (the bundled airfield's unless set).
        eye_offset_m: the pilot's eye from the point the simulator reports (its flight model's
            reference point or centre of gravity), body axes x forward, y right, z down, metres.
        timing: a name of SIMHOST_TIMINGS.
        delay_s: the interpolation delay behind the newest datagram, seconds; 0 takes 1.5
            measured datagram intervals.
        max_extrapolate_s: the longest a pose is carried forward past the newest datagram.
        stale_after_s: the simulator is reported stale after this long without a datagram.
    """

    url: str = ""
    origin: tuple[float, float, float] | None = None
    eye_offset_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    timing: str = "interpolate"
    delay_s: float = 0.0
    max_extrapolate_s: float = 0.1
    stale_after_s: float = 1.0


@dataclass(frozen=True)
class RigChannel:
    """One channel of the rig: its view (a ChannelSpec, see channel_spec) and the address
    (host:port) of its worker's health and status server."""

    spec: ChannelSpec
    address: str
    #: The CIGI view id View Control and View Definition address this channel by.
    view_id: int = 0
    #: The port of its worker's Prometheus metrics (docs/metrics.md); 0: none.
    metrics_port: int = 0

    @property
    def name(self) -> str:
        return self.spec.name


@dataclass(frozen=True)
class Rig:
    """The whole rig; channels in display order, left to right; render: the options every
    worker renders with (the ``[render]`` table; a worker's command line may override them)."""

    host_address: str
    compositor_address: str
    channels: tuple[RigChannel, ...]
    source: str = ""
    render: RenderOptions = field(default_factory=RenderOptions)
    sync: SyncSpec = field(default_factory=SyncSpec)
    blend: BlendSpec = field(default_factory=BlendSpec)
    tls: TlsSpec = field(default_factory=TlsSpec)
    cigi: CigiSpec = field(default_factory=CigiSpec)
    wire: WireSpec = field(default_factory=WireSpec)
    simhost: SimHostSpec = field(default_factory=SimHostSpec)
    #: The scene every process of the rig loads (``[scene] path``, made absolute against the
    #: rig file's folder); "": each command's own default. A --scene flag overrides it.
    scene: str = ""
    #: The ports of the host's and the compositor's Prometheus metrics (``metrics_port`` of
    #: ``[host]`` and ``[compositor]``; docs/metrics.md); 0: none. A --metrics-port flag
    #: overrides them.
    host_metrics_port: int = 0
    compositor_metrics_port: int = 0
    #: The port of the compositor's live view in a browser (``[compositor] view_port``;
    #: docs/live-view.md); 0: none. --view-port overrides it.
    compositor_view_port: int = 0

    def channel(self, name: str) -> RigChannel:
        """The channel called name.

        Raises:
            RigError: no such channel.
        """
        for ch in self.channels:
            if ch.name == name:
                return ch
        raise RigError(f"channel_name: {name!r} is not a channel of the rig "
                       f"({', '.join(self.channel_names)})")

    @property
    def channel_names(self) -> tuple[str, ...]:
        return tuple(ch.name for ch in self.channels)

    def with_size(self, width: int, height: int) -> Rig:
        """The same rig with every channel rendered at width x height pixels."""
        chans = tuple(replace(ch, spec=replace(ch.spec, width=width, height=height)) for ch in self.channels)
        return replace(self, channels=chans)


def default_rig_path() -> Path:
    """The default three-channel rig shipped with the package (same as deploy/rigs/default.toml).

    It is package data (services/rig/data/default_rig.toml), so it is found from an editable
    install, a wheel and a source checkout alike; tests/services/test_rig.py keeps the deploy
    copy identical.
    """
    return Path(__file__).resolve().parent / "data" / "default_rig.toml"


def load_rig(path: str | Path) -> Rig:
    """Read and validate a rig file.

    Raises:
        RigError: unreadable file, invalid TOML, or a bad key or value.
    """
    path = Path(path)
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise RigError(f"{path}: cannot read: {exc.strerror or exc}") from exc
    except tomllib.TOMLDecodeError as exc:
        raise RigError(f"{path}: invalid TOML: {exc}") from exc
    return parse_rig(doc, source=str(path))


_CHANNEL_KEYS = {"name", "address", "yaw_deg", "pitch_deg", "roll_deg", "left_deg", "right_deg",
                 "bottom_deg", "top_deg", "width", "height", "view_id", "metrics_port"}
_OPTIONAL = {"yaw_deg", "pitch_deg", "roll_deg", "view_id", "metrics_port"}


def parse_rig(doc: dict[str, Any], *, source: str = "<rig>") -> Rig:
    """Validate an already-decoded rig document; see load_rig."""
    def fail(where: str, message: str) -> RigError:
        return RigError(f"{source}: {where}: {message}")

    for key in doc:
        if key not in {"host", "compositor", "channels", "render", "sync", "blend", "tls", "cigi",
                       "simhost", "scene"}:
            raise fail(key, "unknown key")
    try:
        render = RenderOptions.from_mapping(doc.get("render", {}), where="render")
    except ValueError as exc:
        raise RigError(f"{source}: {exc}") from None
    addresses = {}
    metrics = {}
    for section, known in (("host", ("address", "metrics_port")),
                           ("compositor", ("address", "wire", "shared_memory", "metrics_port", "view_port"))):
        table = doc.get(section)
        if not isinstance(table, dict) or "address" not in table:
            raise fail(section, "missing table with an 'address' key")
        for key in table:
            if key not in known:
                raise fail(f"{section}.{key}", f"unknown key (known: {', '.join(known)})")
        addresses[section] = _address(table["address"], f"{section}.address", fail)
        metrics[section] = _optional_port(table, section, fail)
    view_port = _optional_port(doc["compositor"], "compositor", fail, key="view_port")
    wire = _wire(doc["compositor"], fail)
    chans = doc.get("channels")
    if not isinstance(chans, list) or not chans:
        raise fail("channels", "expected at least one [[channels]] table")
    if len(chans) > MAX_CHANNELS:
        raise fail("channels", f"{len(chans)} channels, more than the {MAX_CHANNELS} a rig may have")
    out: list[RigChannel] = []
    for i, ch in enumerate(chans):
        where = f"channels[{i}]"
        if not isinstance(ch, dict):
            raise fail(where, f"{ch!r} is not a table")
        for key in sorted(_CHANNEL_KEYS - _OPTIONAL):
            if key not in ch:
                raise fail(where, f"missing key {key!r}")
        for key in ch:
            if key not in _CHANNEL_KEYS:
                raise fail(f"{where}.{key}", "unknown key")
        name = ch["name"]
        if not isinstance(name, str) or not name or not name.replace("_", "").replace("-", "").isalnum():
            raise fail(f"{where}.name", f"{name!r} is not a name (letters, digits, - and _)")
        if name in {c.name for c in out}:
            raise fail(f"{where}.name", f"{name!r} is used twice")
        nums = {}
        for key in ("yaw_deg", "pitch_deg", "roll_deg", "left_deg", "right_deg", "bottom_deg", "top_deg"):
            v = ch.get(key, 0.0)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise fail(f"{where}.{key}", f"{v!r} is not a finite number")
            nums[key] = float(v)
        for key in ("left_deg", "right_deg", "bottom_deg", "top_deg"):
            if not -89.0 <= nums[key] <= 89.0:
                raise fail(f"{where}.{key}", f"{nums[key]} is outside [-89, 89]")
        if not nums["left_deg"] < nums["right_deg"]:
            raise fail(f"{where}.left_deg", f"{nums['left_deg']} is not < right_deg {nums['right_deg']}")
        if not nums["bottom_deg"] < nums["top_deg"]:
            raise fail(f"{where}.bottom_deg", f"{nums['bottom_deg']} is not < top_deg {nums['top_deg']}")
        size = {}
        for key in ("width", "height"):
            v = ch[key]
            if isinstance(v, bool) or not isinstance(v, int) or not 1 <= v <= MAX_CHANNEL_PIXELS:
                raise fail(f"{where}.{key}", f"{v!r} is not a whole number of pixels in [1, {MAX_CHANNEL_PIXELS}]")
            size[key] = v
        # The compositor stitches the channels side by side: one row, one height.
        if out and size["height"] != out[0].spec.height:
            raise fail(f"{where}.height", f"{size['height']} differs from channels[0].height "
                                          f"{out[0].spec.height} (channels are stitched side by side)")
        spec = channel_spec(name, width=size["width"], height=size["height"], **nums)
        view_id = ch.get("view_id", i)
        if isinstance(view_id, bool) or not isinstance(view_id, int) or not 0 <= view_id <= 65535:
            raise fail(f"{where}.view_id", f"{view_id!r} is not a whole number in [0, 65535]")
        if view_id in {c.view_id for c in out}:
            raise fail(f"{where}.view_id", f"{view_id} is used twice")
        out.append(RigChannel(spec, _address(ch["address"], f"{where}.address", fail), view_id,
                              _optional_port(ch, where, fail)))
    # Two services on one address would fail to bind, or worse, answer for each other. A
    # metrics port is taken on the machine of its service's address.
    seen = {addresses["host"]: "host.address"}
    listens = [("compositor.address", addresses["compositor"])] + \
        [(f"channels[{i}].address", c.address) for i, c in enumerate(out)]
    for where, address, port in [("host", addresses["host"], metrics["host"]),
                                 ("compositor", addresses["compositor"], metrics["compositor"])] + \
            [(f"channels[{i}]", c.address, c.metrics_port) for i, c in enumerate(out)]:
        if port:
            listens.append((f"{where}.metrics_port", f"{address.rpartition(':')[0]}:{port}"))
    if view_port:
        listens.append(("compositor.view_port", f"{addresses['compositor'].rpartition(':')[0]}:{view_port}"))
    for where, address in listens:
        if address in seen:
            raise fail(where, f"{address!r} is already used by {seen[address]}")
        seen[address] = where
    sync_table = doc.get("sync", {})
    pace = SyncSpec.pace
    if isinstance(sync_table, dict) and "pace" in sync_table:
        sync_table = dict(sync_table)
        pace = sync_table.pop("pace")
        if not isinstance(pace, str) or pace not in PACES:
            raise fail("sync.pace", f"{pace!r} is not one of {', '.join(PACES)}")
    sync = SyncSpec(**_table({"sync": sync_table}, "sync", {
        "frame_timeout_s": (float, 0.001, 3600.0), "pending_timeout_s": (float, 0.001, 3600.0),
        "max_pending_frames": (int, 1, 4096), "max_pending_mib": (float, 1.0, 65536.0)}, fail,
        also=("pace",)), pace=pace)
    blend = BlendSpec(**_table(doc, "blend", {
        "overlap_deg": (float, 0.0, 45.0), "power": (float, 0.5, 16.0), "gamma": (float, 1.0, 4.0),
        "tolerance_deg": (float, 0.0, 10.0)}, fail))
    tls = _tls(doc.get("tls", {}), Path(source).parent if source != "<rig>" else Path.cwd(), fail)
    cigi = _cigi(doc, tuple(c.name for c in out), fail)
    scene = _scene(doc.get("scene", {}), Path(source).parent if source != "<rig>" else Path.cwd(), fail)
    return Rig(addresses["host"], addresses["compositor"], tuple(out), source, render, sync, blend, tls, cigi, wire,
               _simhost(doc, fail), scene, metrics["host"], metrics["compositor"], view_port)


def _optional_port(table: dict[str, Any], where: str, fail, *, key: str = "metrics_port") -> int:
    """The table's optional metrics_port (docs/metrics.md), or another port key (the
    compositor's view_port); 0 without one."""
    port = table.get(key, 0)
    if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 65535:
        raise fail(f"{where}.{key}", f"{port!r} is not a port in [1, 65535], or 0 for none")
    return port


def scene_path(flag: str | None, rig: Rig, default: str | Path) -> str:
    """The scene a process of the rig loads: the --scene flag, else the rig file's ``[scene]
    path`` (so that host, workers and query service agree without flags), else default (the
    command's own: the bundled airfield for a worker, the terrain scene for `ig demo`)."""
    return str(flag or rig.scene or default)


def _scene(table: Any, base: Path, fail) -> str:
    """The ``[scene]`` table's path, absolute (relative paths against the rig file's folder,
    so that every machine reading the rig file from its own checkout finds the scene); ""
    without one. The file is not opened here: the processes that load it name its errors."""
    if not isinstance(table, dict):
        raise fail("scene", f"{table!r} is not a table")
    for key in table:
        if key != "path":
            raise fail(f"scene.{key}", "unknown key (known: path)")
    if "path" not in table:
        return ""
    value = table["path"]
    if not isinstance(value, str) or not value.strip():
        raise fail("scene.path", f"{value!r} is not a file path")
    return value if Path(value).is_absolute() else str(base / value)


def _wire(table: dict[str, Any], fail) -> WireSpec:
    out: dict[str, Any] = {}
    if "wire" in table:
        if table["wire"] not in WIRE_FORMATS:
            raise fail("compositor.wire", f"{table['wire']!r} is not one of {_one_of(WIRE_FORMATS)}")
        out["format"] = table["wire"]
    if "shared_memory" in table:
        if not isinstance(table["shared_memory"], bool):
            raise fail("compositor.shared_memory", f"{table['shared_memory']!r} is not true or false")
        out["shared_memory"] = table["shared_memory"]
    return WireSpec(**out)


def _cigi(doc: dict[str, Any], channels: tuple[str, ...], fail) -> CigiSpec:
    table = doc.get("cigi", {})
    if not isinstance(table, dict):
        raise fail("cigi", f"{table!r} is not a table")
    known = ("listen", "host_port", "origin", "query_channel", "mode", "stale_after_s", "query_timeout_s", "host",
             "initial_pose")
    for key in table:
        if key not in known:
            raise fail(f"cigi.{key}", f"unknown key (known: {', '.join(known)})")
    out: dict[str, Any] = {}
    if "listen" in table:
        out["listen"] = _address(table["listen"], "cigi.listen", fail)
    if "host_port" in table:
        port = table["host_port"]
        if isinstance(port, bool) or not isinstance(port, int) or not 1 <= port <= 65535:
            raise fail("cigi.host_port", f"{port!r} is not a port in [1, 65535]")
        out["host_port"] = port
    if "initial_pose" in table:
        pose = table["initial_pose"]
        ok = (isinstance(pose, list) and len(pose) == 6
              and all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in pose))
        if not ok or not (abs(pose[0]) <= 90 and abs(pose[1]) <= 180 and -500 <= pose[2] <= 100_000
                          and abs(pose[4]) <= 90 and abs(pose[5]) <= 180):
            raise fail("cigi.initial_pose", f"{pose!r} is not [latitude within +-90, longitude within +-180, "
                       "height in -500..100000 m, heading, pitch within +-90, roll within +-180] (degrees)")
        out["initial_pose"] = tuple(float(v) for v in pose)
    if "origin" in table:
        origin = table["origin"]
        ok = (isinstance(origin, list) and len(origin) == 3
              and all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in origin))
        if not ok or not (abs(origin[0]) <= 90 and abs(origin[1]) <= 180 and abs(origin[2]) <= 20000):
            raise fail("cigi.origin", f"{origin!r} is not [latitude within +-90, longitude within +-180, "
                                      f"height within +-20000 m]")
        out["origin"] = tuple(float(v) for v in origin)
    if "query_channel" in table:
        name = table["query_channel"]
        if name not in channels:
            raise fail("cigi.query_channel", f"{name!r} is not a channel of the rig ({', '.join(channels)})")
        out["query_channel"] = name
    if "host" in table:
        host = table["host"]
        if not isinstance(host, str) or not host or any(c.isspace() for c in host):
            raise fail("cigi.host", f"{host!r} is not a host name or address")
        out["host"] = host
    if "mode" in table:
        if table["mode"] not in ("sync", "async"):
            raise fail("cigi.mode", f"{table['mode']!r} is not 'sync' or 'async'")
        out["mode"] = table["mode"]
    for key, lo, hi in (("stale_after_s", 0.01, 3600.0), ("query_timeout_s", 0.001, 60.0)):
        if key in table:
            v = table[key]
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or not lo <= v <= hi:
                raise fail(f"cigi.{key}", f"{v!r} is not a number in [{lo:g}, {hi:g}]")
            out[key] = float(v)
    return CigiSpec(**out, configured="cigi" in doc)


def _simhost(doc: dict[str, Any], fail) -> SimHostSpec:
    table = doc.get("simhost", {})
    if not isinstance(table, dict):
        raise fail("simhost", f"{table!r} is not a table")
    known = ("url", "origin", "eye_offset_m", "timing", "delay_s", "max_extrapolate_s", "stale_after_s")
    for key in table:
        if key not in known:
            raise fail(f"simhost.{key}", f"unknown key (known: {', '.join(known)})")
    out: dict[str, Any] = {}
    if "url" in table:
        url = table["url"]
        if not isinstance(url, str) or "://" not in url:
            raise fail("simhost.url", f"{url!r} is not a URL (fgfs://HOST:PORT, xplane://HOST:PORT, ...)")
        out["url"] = url

    def triple(key: str) -> tuple[float, float, float] | None:
        v = table[key]
        ok = (isinstance(v, list) and len(v) == 3
              and all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in v))
        return tuple(float(x) for x in v) if ok else None  # type: ignore[return-value]

    if "origin" in table:
        origin = triple("origin")
        if origin is None or not (abs(origin[0]) <= 90 and abs(origin[1]) <= 180 and abs(origin[2]) <= 20000):
            raise fail("simhost.origin", f"{table['origin']!r} is not [latitude within +-90, longitude within "
                                         f"+-180, height within +-20000 m]")
        out["origin"] = origin
    if "eye_offset_m" in table:
        offset = triple("eye_offset_m")
        if offset is None or max(abs(x) for x in offset) > 100.0:
            raise fail("simhost.eye_offset_m", f"{table['eye_offset_m']!r} is not [x forward, y right, z down] "
                                               f"metres, each within +-100")
        out["eye_offset_m"] = offset
    if "timing" in table:
        if table["timing"] not in SIMHOST_TIMINGS:
            raise fail("simhost.timing", f"{table['timing']!r} is not one of {_one_of(tuple(SIMHOST_TIMINGS))}")
        out["timing"] = table["timing"]
    for key, lo, hi in (("delay_s", 0.0, 1.0), ("max_extrapolate_s", 0.0, 1.0), ("stale_after_s", 0.01, 3600.0)):
        if key in table:
            v = table[key]
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or not lo <= v <= hi:
                raise fail(f"simhost.{key}", f"{v!r} is not a number in [{lo:g}, {hi:g}]")
            out[key] = float(v)
    return SimHostSpec(**out)


def _table(doc: dict[str, Any], name: str, keys: dict[str, tuple[type, float, float]], fail, *,
           also: tuple[str, ...] = ()) -> dict[str, Any]:
    """The numeric keys of an optional table, each checked against its type and range; also:
    the table's other keys, read by the caller (named with the known keys)."""
    table = doc.get(name, {})
    if not isinstance(table, dict):
        raise fail(name, f"{table!r} is not a table")
    out: dict[str, Any] = {}
    for key, value in table.items():
        if key not in keys:
            raise fail(f"{name}.{key}", f"unknown key (known: {', '.join((*keys, *also))})")
        kind, lo, hi = keys[key]
        number = isinstance(value, int) if kind is int else isinstance(value, (int, float))
        if isinstance(value, bool) or not number or not math.isfinite(value) or not lo <= value <= hi:
            what = "a whole number" if kind is int else "a number"
            raise fail(f"{name}.{key}", f"{value!r} is not {what} in [{lo:g}, {hi:g}]")
        out[key] = kind(value)
    return out


def _tls(table: Any, base: Path, fail) -> TlsSpec:
    if not isinstance(table, dict):
        raise fail("tls", f"{table!r} is not a table")
    paths: dict[str, str] = {}
    for key, value in table.items():
        if key == "allow_plaintext":
            if not isinstance(value, bool):
                raise fail("tls.allow_plaintext", f"{value!r} is not true or false")
            continue
        if key not in {"ca", "cert", "key"}:
            raise fail(f"tls.{key}", "unknown key (known: ca, cert, key, allow_plaintext)")
        if not isinstance(value, str) or not value:
            raise fail(f"tls.{key}", f"{value!r} is not a file path")
        paths[key] = str(base / value) if not Path(value).is_absolute() else value
    given = sorted(paths)
    if given and given != ["ca", "cert", "key"]:
        missing = sorted({"ca", "cert", "key"} - set(given))
        raise fail("tls", f"{', '.join(missing)} missing: mutual TLS needs ca, cert and key together")
    return TlsSpec(**paths, allow_plaintext=bool(table.get("allow_plaintext", False)))


def channel_spec(name: str, *, width: int, height: int, left_deg: float, right_deg: float, bottom_deg: float,
                 top_deg: float, yaw_deg: float = 0.0, pitch_deg: float = 0.0, roll_deg: float = 0.0) -> ChannelSpec:
    """The pipeline's ChannelSpec of one rig channel.

    Args:
        name: channel name.
        width, height: raster size, pixels.
        left_deg, right_deg, bottom_deg, top_deg: frustum edges in the channel frame, degrees.
        yaw_deg, pitch_deg, roll_deg: the channel's offset from the aircraft nose, degrees.
    """
    return ChannelSpec(name, int(width), int(height), float(left_deg), float(right_deg), float(bottom_deg),
                       float(top_deg), float(yaw_deg), float(pitch_deg), float(roll_deg))


def _address(value: Any, where: str, fail) -> str:
    if not isinstance(value, str) or ":" not in value:
        raise fail(where, f"{value!r} is not host:port")
    host, _, port = value.rpartition(":")
    # Port 0 ("any free port") cannot be in a rig file: the other services must know the port.
    if not host or not port.isdigit() or not 1 <= int(port) <= 65535:
        raise fail(where, f"{value!r} is not host:port with a port in [1, 65535]")
    return value


def rig_toml(rig: Rig) -> str:
    """A rig file for rig (the inverse of parse_rig)."""
    compositor = f'[compositor]\naddress = "{rig.compositor_address}"\n'
    if rig.compositor_metrics_port:
        compositor += f"metrics_port = {rig.compositor_metrics_port}\n"
    if rig.compositor_view_port:
        compositor += f"view_port = {rig.compositor_view_port}\n"
    if rig.wire.format != WireSpec().format:
        compositor += f"wire = {_toml_value(rig.wire.format)}\n"
    if rig.wire.shared_memory != WireSpec().shared_memory:
        compositor += f"shared_memory = {_toml_value(rig.wire.shared_memory)}\n"
    host = f'[host]\naddress = "{rig.host_address}"\n'
    if rig.host_metrics_port:
        host += f"metrics_port = {rig.host_metrics_port}\n"
    lines = [host, compositor]
    changed = {k: v for k, v in rig.render.to_mapping().items() if getattr(RenderOptions(), k) != v}
    if changed:
        lines.append("[render]\n" + "".join(f"{k} = {_toml_value(v)}\n" for k, v in changed.items()))
    for name, spec, default in (("sync", rig.sync, SyncSpec()), ("blend", rig.blend, BlendSpec()),
                                ("tls", rig.tls, TlsSpec()), ("cigi", rig.cigi, CigiSpec()),
                                ("simhost", rig.simhost, SimHostSpec())):
        table = {k: v for k, v in asdict(spec).items() if getattr(default, k) != v and k != "configured"}
        if table or getattr(spec, "configured", False):
            lines.append(f"[{name}]\n" + "".join(f"{k} = {_toml_value(v)}\n" for k, v in table.items()))
    if rig.scene:
        lines.append(f"[scene]\npath = {_toml_value(rig.scene)}\n")
    for ch in rig.channels:
        s = ch.spec
        lines.append(
            f'[[channels]]\nname = "{s.name}"\naddress = "{ch.address}"\n'
            f"yaw_deg = {s.yaw_deg!r}\npitch_deg = {s.pitch_deg!r}\nroll_deg = {s.roll_deg!r}\n"
            f"left_deg = {s.left_deg!r}\nright_deg = {s.right_deg!r}\n"
            f"bottom_deg = {s.bottom_deg!r}\ntop_deg = {s.top_deg!r}\n"
            f"width = {s.width}\nheight = {s.height}\nview_id = {ch.view_id}\n"
            + (f"metrics_port = {ch.metrics_port}\n" if ch.metrics_port else ""))
    return "\n".join(lines)


def _toml_value(value: object) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, (tuple, list)):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    return repr(value)


def port_of(address: str) -> int:
    """The port of a host:port address."""
    return int(address.rpartition(":")[2])


def bind_address(address: str, bind: str | None) -> str:
    """Where a service listens: its rig address, or the same port on `bind` when given
    (for example 0.0.0.0 to accept other machines)."""
    return address if bind is None else f"{bind}:{port_of(address)}"
