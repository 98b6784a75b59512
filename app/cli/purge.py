"""``trajlab purge --older-than DAYS [--status succeeded,failed,...] [--dry-run]``.

Runs against ``TRAJLAB_DATABASE_URL`` directly (an operator's tool, like ``trajlab keys``): it deletes
finished jobs older than DAYS (by when they finished) with their results, and finished studies of that
age with every point, as ``TRAJLAB_RETENTION_DAYS`` does in the recovery loop (app.service.retention).
Prints what it deleted (or, with ``--dry-run``, would delete) and exits 0; a bad argument exits 2.
"""
from __future__ import annotations

import argparse
import math
import sys
from datetime import timedelta


def add_commands(sub) -> None:
    p = sub.add_parser("purge", help="delete finished jobs (and studies) older than DAYS, with their results")
    p.add_argument("--older-than", type=float, required=True, metavar="DAYS",
                   help="finished more than this many days ago (fractions allowed: 0.5 is 12 hours)")
    # the default is resolved on call: importing the models (SQLAlchemy) here would slow every CLI command by seconds
    p.add_argument("--status", default=None,
                   help="comma-separated final statuses to purge (default: every final status)")
    p.add_argument("--dry-run", action="store_true", help="count what would go, delete nothing")
    p.set_defaults(fn=_purge)


def _purge(args: argparse.Namespace) -> int:
    from app.runtime.db import get_database
    from app.runtime.settings import get_settings
    from app.runtime.models import FINAL_STATUSES
    from app.service import retention

    if not (math.isfinite(args.older_than) and args.older_than >= 0):
        print("trajlab purge: --older-than must be a number of days >= 0", file=sys.stderr)
        return 2
    statuses = [s.strip() for s in (args.status or ",".join(FINAL_STATUSES)).split(",") if s.strip()]
    try:
        done = retention.purge(get_database(get_settings().database_url), older_than=timedelta(days=args.older_than),
                               statuses=statuses, dry_run=args.dry_run)
    except ValueError as exc:
        print(f"trajlab purge: {exc}", file=sys.stderr)
        return 2
    verb = "would delete" if args.dry_run else "deleted"
    print(f"{verb} {done['jobs']} job(s) and {done['studies']} study(ies), {done['stored_bytes']} bytes "
          f"(finished more than {args.older_than:g} days ago, status {', '.join(statuses)})")
    return 0
