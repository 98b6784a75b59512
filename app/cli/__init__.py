"""The ``trajlab`` command (:mod:`.commands`; ``main`` is the console script's entry point), its
client subcommands (:mod:`.client_commands`), API key management (:mod:`.keys`) and the Python
HTTP client (:mod:`.client`: ``from app.cli.client import Client``).

Layer rule: the top layer; it may import every other part of ``app``, and nothing in ``app``
imports it.
"""
__all__ = ["main"]


def main(argv=None):
    # imported on call, not here: `python -m app.cli.commands` would otherwise find the module
    # already in sys.modules (through this package) and runpy warns on every start
    from app.cli.commands import main as commands_main

    return commands_main(argv)
