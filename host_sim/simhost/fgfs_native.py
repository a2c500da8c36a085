"""FlightGear's native-fdm datagrams (FGNetFDM): `fgfs://HOST:PORT`, the port this side binds.

FlightGear (`--native-fdm=socket,out,HZ,IGHOST,PORT,udp`) and JSBSim (an `<output
type="FLIGHTGEAR" protocol="UDP">` element) send one datagram of sizeof(FGNetFDM) a tick, every
field big-endian (FlightGear src/Network/native_fdm.cxx and native_structs.cxx; JSBSim
src/input_output/net_fdm.hxx and src/models/output/FGOutputFG.cpp). The first 120 bytes are the
same in both versions spoken:

    off  type     field
    0    uint32   version: 24 (408 bytes: every FlightGear release, JSBSim) or 25 (552 bytes:
                  FlightGear `next` from 2020-10, never released)
    4    uint32   padding
    8    double   longitude, rad
    16   double   geodetic latitude, rad
    24   double   altitude above mean sea level, m
    32   float    agl, m
    36   float    phi (roll), theta (pitch), psi (true heading), rad: Z-Y-X Euler angles
    40   float      against local north-east-down at the aircraft
    44   float
    48.. float    alpha, beta, rates, speeds, accelerations: not used

A datagram is taken only when its version and its length agree, as FlightGear's own reader
requires; `cur_time` (JSBSim sends a constant) is not used: the datagrams are ordered and timed
by arrival.
"""

from __future__ import annotations

import math
import struct

from .receiver import UdpPoseSource
from .stream import Malformed, Pose

#: FGNetFDM version -> datagram length, bytes.
SIZES = {24: 408, 25: 552}

#: version, padding, longitude, latitude, altitude, agl, phi, theta, psi (the fields read).
HEADER = struct.Struct(">II3d4f")


def decode_fgnetfdm(datagram: bytes) -> Pose:
    """The pose of one FGNetFDM datagram.

    Raises:
        Malformed: shorter than 4 bytes or than its version's size (truncated), longer
            (oversized), a version other than 24 or 25 (version; garbage when the length is no
            version's either), or a value that cannot be placed.
    """
    n = len(datagram)
    if n < 4:
        raise Malformed("truncated", f"{n} bytes, not an FGNetFDM")
    version = struct.unpack_from(">I", datagram)[0]
    if version not in SIZES:
        cause = "version" if n in SIZES.values() else "garbage"
        raise Malformed(cause, f"FGNetFDM version {version} ({n} bytes); versions 24 (408 bytes) and 25 "
                               f"(552 bytes) are read")
    size = SIZES[version]
    if n != size:
        raise Malformed("truncated" if n < size else "oversized",
                        f"FGNetFDM version {version} of {n} bytes, not {size}")
    _, _, lon, lat, alt, _agl, phi, theta, psi = HEADER.unpack_from(datagram)
    return Pose(math.degrees(lat), math.degrees(lon), alt, math.degrees(psi), math.degrees(theta),
                math.degrees(phi)).check()


class FgNetFdmSource(UdpPoseSource):
    """`fgfs://HOST:PORT`: FGNetFDM datagrams arriving at HOST:PORT."""

    scheme = "fgfs"

    def decode(self, datagram: bytes) -> Pose:
        return decode_fgnetfdm(datagram)
