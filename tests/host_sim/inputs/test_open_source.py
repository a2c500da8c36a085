"""Control sources are opened by URL; bad URLs are refused naming what is wrong."""

from __future__ import annotations

import pytest

from host_sim.inputs import open_source
from host_sim.inputs.can_bus import CanSource
from host_sim.inputs.serial_panel import SerialPanelSource


def test_can_url_opens_python_can_virtual_bus():
    with open_source("can://virtual/url-test?receive_own_messages=1&stale_after=2") as src:
        assert isinstance(src, CanSource)
        assert src.bus.channel_info  # opened
        assert src.stale_after_s == 2.0 and src.name.startswith("can://virtual/")


def test_serial_plus_url_opens_pyserial_url():
    with open_source("serial+loop://?baud=9600") as src:
        assert isinstance(src, SerialPanelSource)
        assert src.port.baudrate == 9600


@pytest.mark.parametrize("url,words", [
    ("bogus://x", "unknown control source scheme 'bogus'"),
    ("can://virtual/x?bitrat=5", "option 'bitrat' is not a CAN bus option"),
    ("can://virtual/x?bitrate=fast", "bitrate: 'fast' is not a int"),
    ("can://virtual", "expected can://INTERFACE/CHANNEL"),
    ("can://nosuchinterface/x", "cannot open CAN interface 'nosuchinterface'"),
    ("serial:///dev/nonexistent-tty-for-test", "cannot open serial port"),
    ("serial:///dev/ttyUSB0?speed=1", "unknown option(s) speed"),
    ("serial+loop://?baud=x", "baud='x' is not a whole number"),
    ("canlog:///nonexistent/log.asc", "no such file"),
    ("canlog:///tmp/log.txt", "is not a CAN log"),
    ("can://virtual/x?stale_after=0", "stale_after: 0.0 must be"),
    ("can://virtual/x?stale_after=soon", "stale_after='soon'"),
])
def test_bad_urls_are_refused_by_name(url, words):
    with pytest.raises(ValueError) as err:
        open_source(url)
    assert url in str(err.value) and words in str(err.value)


def test_channel_and_device_paths():
    from host_sim.inputs import _channel, _device
    assert _channel("/can0") == "can0"
    assert _channel("/dev/ttyACM0@115200") == "/dev/ttyACM0@115200"
    assert _channel("/loop://") == "loop://"
    assert _channel("/239.74.163.2") == "239.74.163.2"
    assert _device("/COM3") == "COM3" and _device("/dev/ttyUSB0") == "/dev/ttyUSB0"
