"""systemd readiness / watchdog / status notifications, written straight to ``$NOTIFY_SOCKET``.

Why not a library: ``sdnotify`` swallows errors and is unmaintained, ``systemd-python`` needs
libsystemd headers to build. The protocol is one datagram per message on an AF_UNIX socket
(``@`` = abstract namespace), so ~15 lines do it and tests can bind a socket and read them.
Outside systemd (no ``NOTIFY_SOCKET``) every call is a cheap no-op.
"""
from __future__ import annotations

import os
import socket


class SystemdNotifier:
    """Sends READY=1 / WATCHDOG=1 / STATUS=... / STOPPING=1; never raises."""

    def __init__(self, environ=None) -> None:
        env = os.environ if environ is None else environ
        addr = env.get("NOTIFY_SOCKET", "")
        self._addr = "\0" + addr[1:] if addr.startswith("@") else addr
        self._sock = None
        self.errors = 0
        #: systemd's watchdog timeout (s) if it asked this process for pings, else 0
        self.watchdog_s = 0.0
        usec, pid = env.get("WATCHDOG_USEC", ""), env.get("WATCHDOG_PID", "")
        if usec.isdigit() and (not pid or pid == str(os.getpid())):
            self.watchdog_s = int(usec) / 1e6

    @property
    def enabled(self) -> bool:
        return bool(self._addr)

    def notify(self, message: str) -> bool:
        if not self._addr:
            return False
        try:
            if self._sock is None:
                self._sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM | socket.SOCK_CLOEXEC)
            self._sock.sendto(message.encode("utf-8", "replace"), self._addr)
            return True
        except OSError:
            self.errors += 1  # systemd gone or socket full: the daemon keeps running regardless
            return False

    def ready(self, status: str = "") -> bool:
        return self.notify("READY=1" + (f"\nSTATUS={status}" if status else ""))

    def watchdog(self) -> bool:
        return self.notify("WATCHDOG=1")

    def status(self, text: str) -> bool:
        return self.notify("STATUS=" + text.replace("\n", " "))

    def stopping(self) -> bool:
        return self.notify("STOPPING=1")

    def close(self) -> None:
        if self._sock is not None:
            self._sock.close()
            self._sock = None
