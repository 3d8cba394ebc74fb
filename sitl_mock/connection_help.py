"""The connection strings a user pastes into each ground station, for what `mvo-gcs sitl`
serves: a vehicle's own server (TCP as ArduPilot SITL, or UDP waiting to be spoken to), and
the `--out` addresses the vehicles send to (as MAVProxy's outputs, QGroundControl's and
MAVProxy's default UDP port 14550).

MAVSDK 2 and later (4.x here) name the direction: `tcpout://host:port` connects to a
server, `udpout://host:port` sends first, `udpin://host:port` listens (the older
`tcp://` and `udp://:port` forms are deprecated).
"""

from __future__ import annotations


def server_lines(transport: str, host: str, port: int) -> list[str]:
    """How each client connects to one vehicle's own server."""
    if transport == "tcp":
        return [
            f"pymavlink tcp:{host}:{port}",
            f"MAVProxy  mavproxy.py --master=tcp:{host}:{port}",
            f"MAVSDK    tcpout://{host}:{port}",
            f"QGC       Comm Links > Add > TCP, server {host}, port {port}",
        ]
    return [
        f"pymavlink udpout:{host}:{port}",
        f"MAVProxy  mavproxy.py --master=udpout:{host}:{port}",
        f"MAVSDK    udpout://{host}:{port}",
        f"QGC       Comm Links > Add > UDP, server {host}:{port}",
    ]


def output_lines(host: str, port: int) -> list[str]:
    """How each client listens where the vehicles send (every vehicle, one port)."""
    qgc = (
        "QGC       nothing to set: its default UDP link listens on 14550"
        if port == 14550
        else f"QGC       Comm Links > Add > UDP, listening port {port}"
    )
    return [
        f"pymavlink udpin:{host}:{port}",
        f"MAVProxy  mavproxy.py --master=udpin:{host}:{port}",
        f"MAVSDK    udpin://{host}:{port}",
        qgc,
    ]
