"""The ``trajlab`` command (:mod:`.commands`; ``main`` is the console script's entry point), its
client subcommands (:mod:`.client_commands`), API key management (:mod:`.keys`) and the Python
HTTP client (:mod:`.client`: ``from app.cli.client import Client``).

Layer rule: the top layer; it may import every other part of ``app``, and nothing in ``app``
imports it.
"""
from app.cli.commands import main

__all__ = ["main"]
