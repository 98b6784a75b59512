"""``trajlab keys create --name NAME [--owner OWNER] [--admin]``, ``keys list``, ``keys revoke NAME``.

Through the running service's API with an admin key when ``--url``/``TRAJLAB_URL`` names it
(``/v1/admin/keys``), else against the database ``trajlab serve`` uses from here (app.cli.operator).
The key is printed once, on stdout alone, so ``KEY=$(trajlab keys create --name ci)`` captures it;
nothing can show it again.
"""
from __future__ import annotations

import argparse
import sys
from datetime import datetime

from app.cli import operator


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
    for p in ksub.choices.values():
        operator.add_url(p)


def _create(args: argparse.Namespace) -> int:
    name = args.name.strip()
    if not name or len(name) > 100 or (args.owner is not None and not 0 < len(args.owner) <= 100):
        print("trajlab keys: --name and --owner must be 1 to 100 characters", file=sys.stderr)
        return 2

    def create() -> int:
        if operator.service_url(args):
            made = operator.client(args).create_key(name=name, owner=args.owner, admin=args.admin)
            key, owner, admin = made["key"], made["owner"], made["admin"]
        else:
            from app.api import auth

            try:
                info, key = auth.create_key(operator.database(), name=name, owner=args.owner, admin=args.admin)
            except auth.KeyNameTaken:
                print(f"trajlab keys: a key named {name!r} exists already", file=sys.stderr)
                return 1
            owner, admin = info.owner, info.admin
        print(key)
        print(f"created key {name!r} for owner {owner!r}{' (admin)' if admin else ''}; "
              "store it now, it is not shown again", file=sys.stderr)
        return 0

    return operator.run("keys", create)


def _t(value) -> str:
    if value is None:
        return "-"
    dt = datetime.fromisoformat(value) if isinstance(value, str) else value
    return dt.strftime("%Y-%m-%d %H:%M:%S")


def _list(args: argparse.Namespace) -> int:
    def show() -> int:
        if operator.service_url(args):
            rows = operator.client(args).list_keys()
        else:
            import dataclasses

            from app.api import auth

            rows = [dataclasses.asdict(k) for k in auth.list_keys(operator.database())]
        print(f"{'name':<24} {'owner':<24} {'prefix':<10} {'admin':<5} {'created':<20} {'last used':<20} revoked")
        for k in rows:
            print(f"{k['name']:<24} {k['owner']:<24} {k['key_prefix']:<10} {'yes' if k['admin'] else 'no':<5} "
                  f"{_t(k['created_at']):<20} {_t(k['last_used_at']):<20} {_t(k['revoked_at'])}")
        return 0

    return operator.run("keys", show)


def _revoke(args: argparse.Namespace) -> int:
    def revoke() -> int:
        if operator.service_url(args):
            operator.client(args).revoke_key(args.name)   # a 404 names the key (exit 2)
        else:
            from app.api import auth

            if not auth.revoke_key(operator.database(), args.name):
                print(f"trajlab keys: no key named {args.name!r}", file=sys.stderr)
                return 1
        print(f"revoked key {args.name!r}", file=sys.stderr)
        return 0

    return operator.run("keys", revoke)
