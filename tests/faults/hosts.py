"""Hosts of a fault test: network namespaces joined to this one by veth pairs on private addresses.

Each :class:`Host` is ``ip netns add`` plus one veth pair per link, the outer end here with
``10.230.<n>.1/24``, the inner end in the namespace with ``10.230.<n>.2/24``; no default route and no
forwarding, so nothing in a namespace reaches anything but the servers this test binds to those
addresses.  ``cut`` takes the outer end down (the inner end loses its carrier: packets go nowhere,
as when a cable or a switch dies), ``restore`` brings it up.  Everything is removed on ``close``
(deleting a namespace deletes its veth ends and their peers), also when the test fails.  Root only.
"""
from __future__ import annotations

import os
import subprocess
import time

NET = "10.230"


def _ip(*args: str) -> None:
    subprocess.run(["ip", *args], check=True, capture_output=True, timeout=10)


class Host:
    def __init__(self, name: str, links: list[int]):
        self.ns = f"tl30-{os.getpid()}-{name}"
        self.links = links  # one subnet 10.230.<n>.0/24 per link
        self.outer = {n: f"tl{os.getpid() % 100000}{name[:2]}{n}o"[:15] for n in links}
        self.inner = {n: f"tl{os.getpid() % 100000}{name[:2]}{n}i"[:15] for n in links}

    @staticmethod
    def server_address(link: int) -> str:
        """The address on this side of ``link`` (where the servers listen)."""
        return f"{NET}.{link}.1"

    @staticmethod
    def address(link: int) -> str:
        """The namespace's own address on ``link``."""
        return f"{NET}.{link}.2"

    def create(self) -> Host:
        _ip("netns", "add", self.ns)
        _ip("-n", self.ns, "link", "set", "lo", "up")
        for n in self.links:
            _ip("link", "add", self.outer[n], "type", "veth", "peer", "name", self.inner[n], "netns", self.ns)
            _ip("addr", "add", f"{self.server_address(n)}/24", "dev", self.outer[n])
            _ip("link", "set", self.outer[n], "up")
            _ip("-n", self.ns, "addr", "add", f"{self.address(n)}/24", "dev", self.inner[n])
            _ip("-n", self.ns, "link", "set", self.inner[n], "up")
        return self

    def exec_prefix(self) -> tuple[str, ...]:
        return ("ip", "netns", "exec", self.ns)

    def cut(self, link: int) -> float:
        _ip("link", "set", self.outer[link], "down")
        return time.monotonic()

    def restore(self, link: int) -> float:
        _ip("link", "set", self.outer[link], "up")
        return time.monotonic()

    def close(self) -> None:
        for n in self.links:
            subprocess.run(["ip", "link", "del", self.outer[n]], check=False, capture_output=True, timeout=10)
        subprocess.run(["ip", "netns", "del", self.ns], check=False, capture_output=True, timeout=10)
