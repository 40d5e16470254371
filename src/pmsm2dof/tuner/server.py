"""Serving the tuner: bind a socket, run uvicorn on it, in the foreground or in a thread.

The socket is bound here (not by uvicorn) so that the port is known before the server
starts, bad hosts and busy ports become a ConfigError, and ``port=0`` asks the system for
a free port.
"""

import contextlib
import errno
import ipaddress
import socket
import threading
import time

import uvicorn

from ..errors import ConfigError

DEFAULT_PORT = 8765
"""Port tried first when none is given; a free one is chosen if it is busy."""


def is_loopback(host):
    """True if ``host`` is an address or name of this machine's loopback interface."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def bind_socket(host="127.0.0.1", port=None):
    """Return a listening TCP socket on ``host``.

    Parameters
    ----------
    host : str
        Interface address or name.
    port : int or None
        TCP port; 0 lets the system choose a free one; None tries :data:`DEFAULT_PORT`
        and falls back to a free port when it is busy.
    """
    if port is not None and (isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 65535):
        raise ConfigError("port", port, "an integer in [0, 65535]")
    try:
        infos = socket.getaddrinfo(host, None, type=socket.SOCK_STREAM)
    except (socket.gaierror, UnicodeError):
        raise ConfigError("host", host, "an address or name of an interface of this machine") from None
    family, _, _, _, sockaddr = infos[0]
    for candidate in ([DEFAULT_PORT, 0] if port is None else [port]):
        sock = socket.socket(family, socket.SOCK_STREAM)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            sock.bind((sockaddr[0], candidate, *sockaddr[2:]))
        except OSError as exc:
            sock.close()
            if exc.errno == errno.EADDRINUSE and candidate != 0 and port is None:
                continue
            if exc.errno == errno.EADDRINUSE:
                raise ConfigError("port", port, "a free TCP port (this one is in use)") from None
            raise ConfigError("host", host, f"an address of an interface of this machine ({exc.strerror})") from None
        sock.listen(128)
        sock.setblocking(False)
        return sock
    raise AssertionError("unreachable: port 0 always binds")


def url_of(sock):
    """The http URL that reaches the server listening on ``sock`` from this machine."""
    host, port = sock.getsockname()[:2]
    if ipaddress.ip_address(host).is_unspecified:  # all interfaces: loopback is one of them
        host = "127.0.0.1" if sock.family == socket.AF_INET else "::1"
    if ":" in host:
        host = f"[{host}]"
    return f"http://{host}:{port}/"


def make_server(app, sock):
    """A uvicorn server for ``app`` on the bound socket ``sock``, quiet except for errors."""
    host, port = sock.getsockname()[:2]
    config = uvicorn.Config(app, host=host, port=port, log_level="warning", access_log=False, lifespan="off")
    return uvicorn.Server(config)


def serve(app, sock):
    """Serve ``app`` on ``sock`` until interrupted (Ctrl-C)."""
    make_server(app, sock).run(sockets=[sock])


@contextlib.contextmanager
def serving_in_thread(app, host="127.0.0.1", port=0, timeout_s=10.0):
    """Run ``app`` in a background thread; yield its URL; stop it on exit.

    Used by the browser test and the benchmark.
    """
    sock = bind_socket(host, port)
    server = make_server(app, sock)
    thread = threading.Thread(target=server.run, kwargs={"sockets": [sock]}, daemon=True)
    thread.start()
    try:
        deadline = time.monotonic() + timeout_s
        while not server.started:
            if time.monotonic() > deadline or not thread.is_alive():
                raise RuntimeError(f"the tuner server did not start within {timeout_s} s")
            time.sleep(0.01)
        yield url_of(sock)
    finally:
        server.should_exit = True
        thread.join(timeout_s)
        sock.close()
