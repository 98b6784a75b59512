"""Print how long `make run` took to its first answered /healthz (started in the background by `make run`).

It waits for the server `make run` starts (install, migration, Redis, worker, API) and prints the time and
the ``export TRAJLAB_URL=...`` line the README's examples read (any port: ``make run PORT=8211``); if
nothing answers within ``--timeout`` seconds it exits quietly (the server's own output says why).
"""
from __future__ import annotations

import argparse
import sys
import time
import urllib.request


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--port", type=int, required=True)
    parser.add_argument("--since", type=float, required=True, help="Unix time `make run` started")
    parser.add_argument("--timeout", type=float, default=300.0)
    args = parser.parse_args()
    url = f"http://127.0.0.1:{args.port}/healthz"
    while time.time() - args.since < args.timeout:
        try:
            with urllib.request.urlopen(url, timeout=1) as r:
                if r.status == 200:
                    print(f"make run: first /healthz answered {time.time() - args.since:.1f} s after `make run` "
                          f"started (install included). In another terminal, once:\n"
                          f"    export TRAJLAB_URL=http://127.0.0.1:{args.port}\n"
                          f"then every example of the README works as written (.venv/bin/trajlab jobs, "
                          f"curl -s $TRAJLAB_URL/v1/presets)", file=sys.stderr, flush=True)
                    return 0
        except OSError:
            pass
        time.sleep(0.2)
    return 1


if __name__ == "__main__":
    sys.exit(main())
