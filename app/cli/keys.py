"""``trajlab keys create --name NAME [--owner OWNER] [--admin]``, ``keys list``, ``keys revoke NAME``.

Runs against ``TRAJLAB_DATABASE_URL`` directly (an operator's tool, like
``trajlab migrate``): there is no HTTP route that creates keys, so a leaked key
cannot mint more.  The key is printed once, on stdout alone, so
``KEY=$(trajlab keys create --name ci)`` captures it; nothing can show it again.
"""
from __future__ import annotations

import argparse
import sys


def add_commands(sub) -> None:
    keys = sub.add_parser("keys", help="API keys: create, list, revoke (TRAJLAB_AUTH=required)")
    ksub = keys.add_subparsers(dest="keys_command", required=True)
    p = ksub.add_parser("create", help="create a key and print it (shown only this once)")
    p.add_argument("--name", required=True, help="unique name of the key (used to revoke it)")
    p.add_argument("--owner", default=None, help="owner of the jobs submitted with it (default: the name)")
    p.add_argument("--admin", action="store_true", help="sees and cancels every owner's jobs")
    p.set_defaults(fn=_create)
    p = ksub.add_parser("list", help="list keys (names, owners, prefixes; never the keys)")
    p.set_defaults(fn=_list)
    p = ksub.add_parser("revoke", help="revoke a key: its next request is a 401")
    p.add_argument("name")
    p.set_defaults(fn=_revoke)


def _db():
    from app.runtime.db import get_database
    from app.runtime.settings import get_settings

    return get_database(get_settings().database_url)


def _create(args: argparse.Namespace) -> int:
    from app.api import auth

    name = args.name.strip()
    if not name or len(name) > 100 or (args.owner is not None and not 0 < len(args.owner) <= 100):
        print("trajlab keys: --name and --owner must be 1 to 100 characters", file=sys.stderr)
        return 2
    try:
        info, key = auth.create_key(_db(), name=name, owner=args.owner, admin=args.admin)
    except auth.KeyNameTaken:
        print(f"trajlab keys: a key named {name!r} exists already", file=sys.stderr)
        return 1
    print(key)
    print(f"created key {info.name!r} for owner {info.owner!r}{' (admin)' if info.admin else ''}; "
          "store it now, it is not shown again", file=sys.stderr)
    return 0


def _list(args: argparse.Namespace) -> int:
    from app.api import auth

    rows = auth.list_keys(_db())
    print(f"{'name':<24} {'owner':<24} {'prefix':<10} {'admin':<5} {'created':<20} {'last used':<20} revoked")
    for k in rows:
        def t(dt):
            return dt.strftime("%Y-%m-%d %H:%M:%S") if dt else "-"
        print(f"{k.name:<24} {k.owner:<24} {k.key_prefix:<10} {'yes' if k.admin else 'no':<5} "
              f"{t(k.created_at):<20} {t(k.last_used_at):<20} {t(k.revoked_at)}")
    return 0


def _revoke(args: argparse.Namespace) -> int:
    from app.api import auth

    if not auth.revoke_key(_db(), args.name):
        print(f"trajlab keys: no key named {args.name!r}", file=sys.stderr)
        return 1
    print(f"revoked key {args.name!r}", file=sys.stderr)
    return 0
