"""``trajlab purge --older-than DAYS [--status succeeded,failed,...] [--dry-run]``.

Through the running service's API with an admin key when ``--url``/``TRAJLAB_URL`` names it
(``/v1/admin/purge``), else against the database ``trajlab serve`` uses from here (app.cli.operator): it deletes
finished jobs older than DAYS (by when they finished) with their results, and finished studies of that
age with every point, as ``TRAJLAB_RETENTION_DAYS`` does in the recovery loop (app.service.retention).
Prints what it deleted (or, with ``--dry-run``, would delete) and exits 0; a bad argument exits 2.
"""
from __future__ import annotations

import argparse
import math
import sys
from datetime import timedelta

from app.cli import operator


def add_commands(sub) -> None:
    p = sub.add_parser("purge", help="delete finished jobs (and studies) older than DAYS, with their results")
    p.add_argument("--older-than", type=float, required=True, metavar="DAYS",
                   help="finished more than this many days ago (fractions allowed: 0.5 is 12 hours)")
    # the default is resolved on call: importing the models (SQLAlchemy) here would slow every CLI command by seconds
    p.add_argument("--status", default=None,
                   help="comma-separated final statuses to purge (default: every final status)")
    p.add_argument("--dry-run", action="store_true", help="count what would go, delete nothing")
    operator.add_url(p)
    p.set_defaults(fn=_purge)


def _purge(args: argparse.Namespace) -> int:
    if not (math.isfinite(args.older_than) and 0 <= args.older_than <= 36525):
        print("trajlab purge: --older-than must be a number of days from 0 to 36525 (a century)", file=sys.stderr)
        return 2
    given = [s.strip() for s in (args.status or "").split(",") if s.strip()]

    def purge() -> int:
        if operator.service_url(args):
            done = operator.client(args).purge(older_than_days=args.older_than, statuses=given or None,
                                               dry_run=args.dry_run)
            statuses = given or ["every final status"]
        else:
            from app.runtime.models import FINAL_STATUSES
            from app.service import retention

            statuses = given or list(FINAL_STATUSES)
            try:
                done = retention.purge(operator.database(), older_than=timedelta(days=args.older_than),
                                       statuses=statuses, dry_run=args.dry_run)
            except ValueError as exc:
                print(f"trajlab purge: {exc}", file=sys.stderr)
                return 2
        verb = "would delete" if args.dry_run else "deleted"
        print(f"{verb} {done['jobs']} job(s) and {done['studies']} study(ies), {done['stored_bytes']} bytes "
              f"(finished more than {args.older_than:g} days ago, status {', '.join(statuses)})")
        return 0

    return operator.run("purge", purge)
