"""Where the drive is and how to reach it: the link URL and a pyxcp master on its transport.

:func:`link_url` reads the forms a user gives (``tcp://HOST:PORT`` for XCP on TCP, the PC's drive or
QEMU's ``-serial tcp``; ``serial:DEVICE`` or a device path for XCP on SxI, a UART or QEMU's
``-serial pty``; ``can://INTERFACE/CHANNEL?...`` for XCP on CAN through python-can), refusing a TCP
host other than this machine unless allowed; :func:`pyxcp_master` opens pyxcp on it.
"""

from typing import Any

from ..errors import ConfigError

#: The forms of a link URL, for messages.
URL_FORMS = (
    "tcp://HOST:PORT (XCP on TCP), serial:DEVICE or a device path such as /dev/pts/3 or COM3 (XCP on SxI), "
    "can://INTERFACE/CHANNEL?master=ID&slave=ID&fd=0|1&bitrate=N (XCP on CAN by python-can)"
)
#: The CAN identifiers of XCP on CAN unless the URL names others: master -> slave and slave -> master.
CAN_IDS = (0x7E0, 0x7E1)
#: Options of a can:// URL and their defaults.
CAN_OPTIONS = {"master": CAN_IDS[0], "slave": CAN_IDS[1], "fd": 0, "bitrate": 500_000}


def can_url(text: str) -> dict[str, Any]:
    """The parts of ``can://INTERFACE/CHANNEL?master=ID&slave=ID&fd=0|1&bitrate=N`` (XCP on CAN by python-can).

    INTERFACE is a python-can interface (``socketcan``, ``pcan``, ``vector``, ``udp_multicast``, ...),
    CHANNEL its channel (``can0``, ``PCAN_USBBUS1``, a multicast group such as ``239.74.163.2``);
    ``master`` and ``slave`` the CAN identifiers of the two directions (11 bits, or 29 with
    ``0x80000000`` set: extended), ``fd=1`` CAN FD (64-byte frames), ``bitrate`` the arbitration rate
    [bit/s]. Raises ConfigError naming the part that is wrong.
    """
    from urllib.parse import parse_qsl

    from can.interfaces import VALID_INTERFACES

    rest = text[len("can://") :]
    where, _, query = rest.partition("?")
    interface, _, channel = where.partition("/")
    if interface not in VALID_INTERFACES:
        raise ConfigError(
            "link", text, "can://INTERFACE/CHANNEL, INTERFACE one of " + ", ".join(sorted(VALID_INTERFACES))
        )
    if not channel:
        raise ConfigError("link", text, "can://INTERFACE/CHANNEL?...: a channel (can0, PCAN_USBBUS1, 239.74.163.2)")
    out: dict[str, Any] = {"interface": interface, "channel": channel, **CAN_OPTIONS}
    for key, value in parse_qsl(query, keep_blank_values=True):
        if key not in CAN_OPTIONS:
            raise ConfigError("link", text, "options " + ", ".join(f"{k}=" for k in CAN_OPTIONS) + " of a can:// URL")
        try:
            number = int(value, 0)
        except ValueError:
            number = -1
        valid = {
            "master": (0, 0x9FFFFFFF), "slave": (0, 0x9FFFFFFF), "fd": (0, 1), "bitrate": (10_000, 8_000_000),
        }[key]  # fmt: skip
        extended = number & 0x80000000
        if not valid[0] <= number <= valid[1] or (
            key in ("master", "slave") and number > (0x1FFFFFFF if extended else 0x7FF) | extended
        ):
            names = {"master": "a CAN identifier: 0..0x7FF, or 0x80000000 | 0..0x1FFFFFFF (extended)",
                     "slave": "a CAN identifier: 0..0x7FF, or 0x80000000 | 0..0x1FFFFFFF (extended)",
                     "fd": "0 or 1", "bitrate": "10000..8000000 bit/s"}  # fmt: skip
            raise ConfigError(f"link {key}", value, names[key])
        out[key] = number
    if out["master"] == out["slave"]:
        raise ConfigError("link slave", hex(out["slave"]), "another identifier than master's")
    return out


def link_url(text: str, allow_remote: bool = False) -> str:
    """A link URL checked, in one form: ``tcp://HOST:PORT`` or a device.

    Parameters
    ----------
    text : str
        ``tcp://HOST:PORT`` (also ``socket://HOST:PORT``), ``serial:DEVICE``, or a device path.
    allow_remote : bool
        Accept a HOST that is not this machine's loopback. A drive answers whoever connects to it
        (XCP has no authentication unless the integrator adds seed and key): a master reaches
        another machine's drive only when told to.

    Raises
    ------
    ConfigError
        Another form, a port outside 1..65535, or a remote HOST without ``allow_remote``.
    """
    import ipaddress

    if text.startswith("can://"):
        c = can_url(text)
        return (f"can://{c['interface']}/{c['channel']}?master=0x{c['master']:X}&slave=0x{c['slave']:X}"
                f"&fd={c['fd']}&bitrate={c['bitrate']}")  # fmt: skip
    for scheme in ("tcp://", "socket://"):
        if text.startswith(scheme):
            host, _, port = text[len(scheme) :].rpartition(":")
            host = host.strip("[]")
            if not host or not port.isdigit() or not 1 <= int(port) <= 65535:
                raise ConfigError("link", text, URL_FORMS + ", PORT in 1..65535")
            if not allow_remote:
                try:
                    local = host == "localhost" or ipaddress.ip_address(host).is_loopback
                except ValueError:
                    local = False
                if not local:
                    raise ConfigError(
                        "link",
                        text,
                        "a drive on this machine (127.0.0.1, ::1, localhost); allow a remote one explicitly",
                    )
            return f"tcp://{host}:{int(port)}"
    device = text[len("serial:") :] if text.startswith("serial:") else text
    if not device or "://" in device:
        raise ConfigError("link", text, URL_FORMS)
    return device


def pyxcp_master(url: str, timeout_s: float = 2.0, policy: Any = None) -> Any:
    """A pyxcp Master on ``url`` (``tcp://host:port``, ``socket://host:port`` or a device) that raises on errors."""
    from pyxcp import Master
    from pyxcp.config import create_application_from_config

    general = {"disable_error_handling": True}
    if url.startswith(("socket://", "tcp://")):
        host, _, port = url.partition("://")[2].rpartition(":")
        if not host or not port.isdigit():
            raise ConfigError("url", url, "socket://HOST:PORT or a serial device")
        transport = {"timeout": timeout_s, "Eth": {"host": host, "port": int(port), "protocol": "TCP"}}
        name = "eth"
    elif url.startswith("can://"):
        c = can_url(url)
        transport = {
            "timeout": timeout_s,
            "CAN": {"interface": c["interface"], "channel": c["channel"], "can_id_master": c["master"],
                    "can_id_slave": c["slave"], "fd": bool(c["fd"]), "bitrate": c["bitrate"]},
        }  # fmt: skip
        name = "can"
    else:
        transport = {
            "timeout": timeout_s,
            "SxI": {
                "port": url,
                "bitrate": 115200,
                "header_format": "HEADER_LEN_CTR_WORD",
                "tail_format": "NO_CHECKSUM",
            },
        }
        name = "sxi"
    config = create_application_from_config({"Transport": transport, "General": general}, log_level=50)
    return Master(name, config=config, policy=policy)


def use_default_application() -> None:
    """pyxcp's DAQ policies read its global application configuration, which pyxcp would otherwise build from
    sys.argv: a default one."""
    from pyxcp.config import create_application_from_config, set_application

    set_application(create_application_from_config({}, log_level=50))
