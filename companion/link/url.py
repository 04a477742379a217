"""Connection strings: where the autopilot is and how to reach it.

    udp://HOST:PORT  udpout://HOST:PORT   send to a vehicle that listens there (the bundled one)
    udpin://HOST:PORT                     listen there for a vehicle that sends first (PX4 SITL: 14540)
    tcp://HOST:PORT                       a TCP server (ArduPilot SITL's SERIAL0: 5760)
    serial:///dev/ttyAMA0:921600          a serial port at a baud rate (a flight controller's TELEM2);
    serial:/dev/ttyUSB0:57600             also MAVSDK's forms, and serial_flowcontrol:// for RTS/CTS

A malformed string is a ValueError whose text says what was expected: the command line prints it
as one line and exits 2.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

__all__ = ["Endpoint", "parse_endpoint", "parse_url", "BAUD_RATES"]

BAUD_RATES = (9600, 19200, 38400, 57600, 115200, 230400, 460800, 500000, 576000, 921600, 1000000, 1500000,
              2000000, 3000000)
_EXPECTED = ("expected udp://HOST:PORT, udpin://HOST:PORT, tcp://HOST:PORT or serial:///dev/DEVICE:BAUD "
             "(e.g. udpin://0.0.0.0:14540, tcp://127.0.0.1:5760, serial:///dev/ttyAMA0:921600)")
_HOST = re.compile(r"^[A-Za-z0-9.\-]+$")


@dataclass(frozen=True)
class Endpoint:
    kind: str
    """udpout | udpin | tcp | serial"""
    host: str = ""
    port: int = 0
    device: str = ""
    baud: int = 0
    flow_control: bool = False

    @property
    def url(self) -> str:
        if self.kind == "serial":
            return f"serial{'_flowcontrol' if self.flow_control else ''}://{self.device}:{self.baud}"
        return f"{self.kind}://{self.host}:{self.port}"


def parse_endpoint(url: str) -> Endpoint:
    scheme, sep, rest = url.partition("://")
    if not sep and url.startswith("serial:"):
        scheme, rest = "serial", url[len("serial:"):]
    elif not sep:
        raise ValueError(f"--connect {url!r}: {_EXPECTED}")
    if scheme in ("serial", "serial_flowcontrol"):
        device, _, baud = rest.rpartition(":")
        if not device.startswith("/") or not baud.isdigit():
            raise ValueError(f"--connect {url!r}: expected serial:///dev/DEVICE:BAUD (e.g. serial:///dev/ttyAMA0:921600)")
        if int(baud) not in BAUD_RATES:
            raise ValueError(f"--connect {url!r}: baud rate {baud} is not one of {', '.join(map(str, BAUD_RATES))}")
        return Endpoint("serial", device=device, baud=int(baud), flow_control=scheme == "serial_flowcontrol")
    host, _, port = rest.rpartition(":")
    kinds = {"udp": "udpout", "udpout": "udpout", "udpin": "udpin", "tcp": "tcp"}
    lowest = 0 if scheme == "udpin" else 1  # udpin on port 0: any free port (tests)
    if scheme not in kinds or not port.isdigit() or not lowest <= int(port) < 65536 or (host and not _HOST.match(host)):
        raise ValueError(f"--connect {url!r}: {_EXPECTED}")
    if not host:
        host = "0.0.0.0" if scheme == "udpin" else "127.0.0.1"
    return Endpoint(kinds[scheme], host, int(port))


def parse_url(url: str) -> tuple[str, str, int]:
    """UDP only (the MAVSDK backend's tap and older callers): ``(in|out, host, port)``."""
    e = parse_endpoint(url)
    if e.kind not in ("udpin", "udpout"):
        raise ValueError(f"--connect {url!r}: expected a udp:// or udpin:// address here")
    return ("in" if e.kind == "udpin" else "out"), e.host, e.port
