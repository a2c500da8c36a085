"""FlightGear's generic protocol with the rig's layout: `fgfs-generic://HOST:PORT`.

deploy/flightgear/ig.xml, copied to $FG_ROOT/Protocol/ig.xml, makes
`fgfs --generic=socket,out,60,IGHOST,PORT,udp,ig` send one binary datagram a tick, big-endian
(the generic protocol's default byte order: FlightGear src/Network/generic.cxx):

    off  type    property (unit)
    0    double  /sim/time/elapsed-sec (s): orders the datagrams; going back > 1 s: a restart
    8    double  /position/latitude-deg
    16   double  /position/longitude-deg
    24   double  /position/altitude-ft times 0.3048 (m above mean sea level)
    32   float   /orientation/roll-deg
    36   float   /orientation/pitch-deg
    40   float   /orientation/heading-deg (true)
    44   float   /sim/current-view/x-offset-m, y-offset-m, z-offset-m (the view's eye in the
    48   float     aircraft model: right, up, aft, m)
    52   float
    56   float   /sim/current-view/heading-offset-deg, pitch-offset-deg, roll-offset-deg
    60   float
    64   float
    68           length

The view offsets are shown in the status (to copy into the rig file's eye offset) and are not
applied: the rig's channels look where the rig file points them, not where FlightGear's pilot
turns his head.
"""

from __future__ import annotations

import struct

from .receiver import UdpPoseSource
from .stream import Malformed, Pose

#: The ig.xml layout (the table above); tests/host_sim/simhost holds ig.xml to it.
LAYOUT = struct.Struct(">4d9f")

#: The chunks of ig.xml in order: (property, struct code, factor).
CHUNKS = (("/sim/time/elapsed-sec", "d", 1.0), ("/position/latitude-deg", "d", 1.0),
          ("/position/longitude-deg", "d", 1.0), ("/position/altitude-ft", "d", 0.3048),
          ("/orientation/roll-deg", "f", 1.0), ("/orientation/pitch-deg", "f", 1.0),
          ("/orientation/heading-deg", "f", 1.0), ("/sim/current-view/x-offset-m", "f", 1.0),
          ("/sim/current-view/y-offset-m", "f", 1.0), ("/sim/current-view/z-offset-m", "f", 1.0),
          ("/sim/current-view/heading-offset-deg", "f", 1.0), ("/sim/current-view/pitch-offset-deg", "f", 1.0),
          ("/sim/current-view/roll-offset-deg", "f", 1.0))


def decode_generic(datagram: bytes) -> Pose:
    """The pose of one ig.xml datagram.

    Raises:
        Malformed: not LAYOUT.size bytes (truncated, oversized), or a value that cannot be placed.
    """
    n = len(datagram)
    if n != LAYOUT.size:
        raise Malformed("truncated" if n < LAYOUT.size else "oversized",
                        f"{n} bytes, not the {LAYOUT.size} of deploy/flightgear/ig.xml")
    t, lat, lon, alt, roll, pitch, heading, vx, vy, vz, vh, vp, vr = LAYOUT.unpack(datagram)
    extra = (("view_x_offset_m", vx), ("view_y_offset_m", vy), ("view_z_offset_m", vz),
             ("view_heading_offset_deg", vh), ("view_pitch_offset_deg", vp), ("view_roll_offset_deg", vr))
    return Pose(lat, lon, alt, heading, pitch, roll, host_time_s=t, extra=extra).check()


class FgGenericSource(UdpPoseSource):
    """`fgfs-generic://HOST:PORT`: ig.xml datagrams arriving at HOST:PORT."""

    scheme = "fgfs-generic"

    def decode(self, datagram: bytes) -> Pose:
        return decode_generic(datagram)
