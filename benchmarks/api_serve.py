"""Serve an ASGI app as ``trajlab api`` serves trajlab's, for ``benchmarks.api_load``'s baseline: like with like.

``python -m benchmarks.api_serve benchmarks.api_baseline_app:app --host 127.0.0.1 --port 8000 --workers 2``:
uvicorn with uvloop and httptools, no access log, and above one process each process on a listening
socket of its own (``app.runtime.serving``), as ``trajlab api`` runs.
"""
from __future__ import annotations

import argparse

import uvicorn

from app.runtime.serving import run_processes


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("app", help="module:attribute of the ASGI app")
    ap.add_argument("--host", default="127.0.0.1")
    ap.add_argument("--port", type=int, default=8000)
    ap.add_argument("--workers", type=int, default=1)
    args = ap.parse_args()
    options = dict(host=args.host, port=args.port, loop="uvloop", http="httptools", access_log=False,
                   workers=args.workers)
    if args.workers == 1:
        uvicorn.run(args.app, **options)
    else:
        run_processes(uvicorn.Config(args.app, **options))


if __name__ == "__main__":
    main()
