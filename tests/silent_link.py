"""A TCP relay to a real server that can fall silent, as a link that drops packets does.

While cut, everything either side sends is held, unanswered, and delivered in order when the link is
restored, as TCP's retransmissions deliver it once a dead link comes back: a client sees only silence (its
reply timeout), never a reset; and a request it gave up on may still reach the server later.  New
connections are accepted by the relay even while cut (where a real dead link would time out the connect),
which a client sees as the same silence one step later.  Used without root, on 127.0.0.1, where network
namespaces (tests/faults/hosts.py) are not available.
"""
from __future__ import annotations

import socket
import threading


class SilentLink:
    def __init__(self, host: str, port: int):
        self.target = (host, port)
        self._open = threading.Event()
        self._open.set()
        self._listener = socket.create_server(("127.0.0.1", 0))
        self.port = self._listener.getsockname()[1]
        self._closed = False
        self._sockets: list[socket.socket] = []
        threading.Thread(target=self._accept, daemon=True).start()

    def url(self, db: int | str = 0) -> str:
        return f"redis://127.0.0.1:{self.port}/{db}"

    def cut(self) -> None:
        self._open.clear()

    def restore(self) -> None:
        self._open.set()

    def close(self) -> None:
        self._closed = True
        self._open.set()
        for s in [self._listener, *self._sockets]:
            try:
                s.close()
            except OSError:
                pass

    def _accept(self) -> None:
        while not self._closed:
            try:
                client, _ = self._listener.accept()
                upstream = socket.create_connection(self.target, timeout=10)
            except OSError:
                return
            upstream.settimeout(None)
            self._sockets += [client, upstream]
            for src, dst in ((client, upstream), (upstream, client)):
                threading.Thread(target=self._pump, args=(src, dst), daemon=True).start()

    def _pump(self, src: socket.socket, dst: socket.socket) -> None:
        try:
            while data := src.recv(65536):
                self._open.wait()  # held while cut, delivered when restored
                dst.sendall(data)
        except OSError:
            pass
        finally:
            for s in (src, dst):
                try:
                    s.shutdown(socket.SHUT_RDWR)
                except OSError:
                    pass
