"""A small Server-Sent Events reader for tests and the CLI's tests (the wire format, parsed by hand)."""
from __future__ import annotations

import json
from typing import Iterable, Iterator


def parse_sse(lines: Iterable[str]) -> Iterator[dict]:
    """Events as dicts ``{"event", "id", "data"}`` (data JSON-decoded); comments are skipped."""
    event: dict = {}
    for line in lines:
        if line == "":
            if "data" in event:
                event["data"] = json.loads(event["data"])
                yield event
            event = {}
        elif line.startswith(":"):
            continue
        else:
            field, _, value = line.partition(":")
            value = value.removeprefix(" ")
            if field == "data" and "data" in event:
                event["data"] += "\n" + value
            elif field in ("event", "id", "data", "retry"):
                event[field] = value
