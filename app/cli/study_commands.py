"""``trajlab study submit | wait | result | list``: trade studies from the command line.

A study sweeps one parameter (or two) over a base job; each point is an
ordinary job (``POST /v1/studies``, README "Trade studies").  The exit codes are
the job commands' (``app.cli.client_commands``): 0 the study finished (each
point has a final status; an infeasible point is an answer, not an error), 2 bad
input, 3 cancelled, 4 the service cannot be reached.  The progress bar is the
jobs' bar, fed by polling the study (a study has no event stream of its own).
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

from app.cli.client_commands import parse_set, progress_bar

EXIT = {"finished": 0, "cancelled": 3}


def _client(args):
    from app.cli.client import Client

    return Client(args.url)


def _force_bar() -> bool:
    import os

    return os.environ.get("TRAJLAB_PROGRESS") == "bar"  # as the job commands: a bar even when not a terminal


def _line(study: dict) -> str:
    counts = " ".join(f"{k} {v}" for k, v in sorted(study["points_by_status"].items()))
    return f"{study['status']}: {counts}"


def _print_study(study: dict) -> None:
    print(f"{study['id']}  {study['kind']:<15} {study['mode']:<12} {study['status']:<10} "
          f"{study['progress'] * 100:5.1f}%  {study['points']:>3} points  {(study.get('label') or '')[:30]}")


def _follow(client, study_id: str, *, quiet: bool, timeout: float | None = None) -> dict:
    """Wait for the study with the jobs' progress bar (rich, on stderr), or plain lines when not a terminal."""
    if quiet or not sys.stderr.isatty() and not _force_bar():
        last: list[str | None] = [None]

        def line(study):
            text = _line(study)
            if not quiet and text != last[0]:
                last[0] = text
                print(f"{study['progress'] * 100:5.1f}%  {text}", file=sys.stderr)

        return client.wait_study(study_id, on_update=line, timeout=timeout)
    with progress_bar(study_id) as show:
        return client.wait_study(study_id, on_update=lambda study: show(study["progress"], _line(study)[:60]),
                                 timeout=timeout)


def _print_rows(rows: list[dict]) -> None:
    """The trade table as aligned text: swept values, status, key numbers, job id."""
    if not rows:
        return
    columns = [c for c in dict.fromkeys(k for r in rows for k in r) if c != "index"]

    def cell(v):
        if isinstance(v, float):
            return f"{v:.6g}"
        return "" if v is None else str(v)

    table = [[cell(r.get(c)) for c in columns] for r in rows]
    widths = [max(len(c), *(len(row[i]) for row in table)) for i, c in enumerate(columns)]
    print("  ".join(c.ljust(w) for c, w in zip(columns, widths)))
    for row in table:
        print("  ".join(v.ljust(w) for v, w in zip(row, widths)))


def cmd_study_submit(args) -> int:
    params: dict = json.loads(Path(args.params).read_text()) if args.params else {}
    body = json.loads(Path(args.file).read_text()) if args.file else {}
    from app.runtime.merge import deep_merge

    params = deep_merge(body.pop("params", {}) or {}, deep_merge(params, parse_set(args.set or [])))
    sweeps = [json.loads(s) for s in args.sweep] if args.sweep else body.pop("sweeps", None)
    client = _client(args)
    study = client.submit_study(
        study_preset=args.study_preset or body.pop("study_preset", None), kind=args.kind or body.pop("kind", None),
        preset=args.preset or body.pop("preset", None), params=params or None, sweeps=sweeps,
        mode=args.mode or body.pop("mode", None), label=args.label or body.pop("label", None))
    print(study["id"])
    if not args.wait:
        return 0
    return _finish(client, study["id"], quiet=args.quiet)


def _finish(client, study_id: str, *, quiet: bool) -> int:
    study = _follow(client, study_id, quiet=quiet)
    _print_study(study)
    _print_rows(client.study_result(study_id)["rows"])
    return EXIT.get(study["status"], 1)


def cmd_study_wait(args) -> int:
    return _finish(_client(args), args.id, quiet=args.quiet)


def cmd_study_result(args) -> int:
    client = _client(args)
    if args.csv or args.json:
        text = client.study_result_csv(args.id) if args.csv else json.dumps(client.study_result(args.id), indent=2)
        if args.out:
            Path(args.out).write_text(text)
        else:
            sys.stdout.write(text if text.endswith("\n") else text + "\n")
        return 0
    result = client.study_result(args.id)
    _print_study(result["study"])
    _print_rows(result["rows"])
    return 0


def cmd_study_list(args) -> int:
    studies = _client(args).list_studies(limit=args.limit)
    for study in studies:
        _print_study(study)
    print(f"{len(studies)} studies", file=sys.stderr)
    return 0


def cmd_study_delete(args) -> int:
    _client(args).delete_study(args.id)
    print(f"{args.id}  deleted with its jobs")
    return 0


def add_commands(sub) -> None:
    study = sub.add_parser("study", help="trade studies: submit, wait, result, list, delete")
    verbs = study.add_subparsers(dest="study_command", required=True, metavar="{submit,wait,result,list,delete}")

    def common(p):
        p.add_argument("--url", help="trajlab service URL (TRAJLAB_URL; default http://127.0.0.1:8000)")
        p.set_defaults(run_client=True)
        return p

    p = common(verbs.add_parser("submit", help="submit a study: a named one (--study-preset) or a base job "
                                               "with --sweep and --mode (add --wait for a progress bar)"))
    p.add_argument("--study-preset", help="a named study, e.g. crossrange-vs-heating (GET /v1/studies/presets)")
    p.add_argument("--file", metavar="FILE", help="a JSON study body, as POST /v1/studies takes (e.g. examples/)")
    p.add_argument("--kind")
    p.add_argument("--preset", help="the base job's preset")
    p.add_argument("--set", action="append", metavar="PATH=VALUE", help="override one base parameter (repeatable)")
    p.add_argument("--params", metavar="FILE", help="a JSON file of base parameters")
    p.add_argument("--sweep", action="append", metavar="JSON",
                   help='a sweep, e.g. \'{"path": "grid.intervals", "values": [20, 40]}\' (at most two)')
    p.add_argument("--mode", choices=("independent", "continuation"))
    p.add_argument("--label")
    p.add_argument("--wait", action="store_true")
    p.add_argument("--quiet", action="store_true", help="no progress output")
    p.set_defaults(fn=cmd_study_submit)
    p = common(verbs.add_parser("wait", help="follow a study to its end with a progress bar, then its table"))
    p.add_argument("id")
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(fn=cmd_study_wait)
    p = common(verbs.add_parser("result", help="a study's trade table (text, --json or --csv)"))
    p.add_argument("id")
    p.add_argument("--json", action="store_true")
    p.add_argument("--csv", action="store_true")
    p.add_argument("--out", metavar="FILE")
    p.set_defaults(fn=cmd_study_result)
    p = common(verbs.add_parser("list", help="studies, newest first"))
    p.add_argument("--limit", type=int, default=20)
    p.set_defaults(fn=cmd_study_list)
    p = common(verbs.add_parser("delete", help="delete a study with every point job (running points cancelled)"))
    p.add_argument("id")
    p.set_defaults(fn=cmd_study_delete)
