"""``trajlab submit | jobs | show | wait | cancel | result | delete | usage | presets | vehicles``: the
command-line client of any trajlab URL.  It imports no part of the service (FastAPI, SQLAlchemy, the kinds,
CasADi, numpy): httpx, and rich for a progress bar; what needs a kind (headlines, key numbers, a failure's
explanation) it asks the service for.

Exit codes a script can use: 0 succeeded (or done), 1 failed, 2 bad input
(the API's 4xx, printed as its one-line message), 3 cancelled, 4 the service
cannot be reached.  ``--url``/``TRAJLAB_URL`` pick the service (default the
local one), ``TRAJLAB_API_KEY`` the key.
"""
from __future__ import annotations

import contextlib
import json
import sys
from pathlib import Path

EXIT = {"succeeded": 0, "failed": 1, "cancelled": 3}
EXIT_BAD_INPUT, EXIT_UNREACHABLE = 2, 4


def parse_set(items: list[str]) -> dict:
    """``a.b.c=value`` pairs to a nested dict; a value is JSON when it parses (numbers, lists, null), else a string."""
    out: dict = {}
    for item in items:
        path, sep, raw = item.partition("=")
        if not sep or not path or any(not p for p in path.split(".")):
            raise ValueError(f"--set {item!r}: expected path.to.field=value")
        try:
            value = json.loads(raw)
        except ValueError:
            value = raw
        node = out
        *parents, leaf = path.split(".")
        for p in parents:
            node = node.setdefault(p, {})
            if not isinstance(node, dict):
                raise ValueError(f"--set {item!r}: {p} is set to a value and used as a group")
        node[leaf] = value
    return out


def _print_job(job: dict) -> None:
    print(f"{job['id']}  {job['kind']:<15} {job['status']:<10} {job['progress'] * 100:5.1f}%  "
          f"{(job.get('label') or '')[:30]:<30} {job['message'][:60]}")


def _print_numbers(client, job: dict) -> None:
    """The headline numbers, then the key numbers; a failure explained with what to try, on stderr.  The
    service computes all three (its kinds declare them): the client imports no kind, so it starts in
    a fraction of a second (issue 38)."""
    if job["status"] not in ("succeeded", "failed"):
        return
    summary = client.summary(job["id"])
    if job["status"] == "succeeded":
        for line in summary.get("headlines") or []:
            print(f"= {line['text']}")
        for name, value in client.numbers(job["id"]).items():
            print(f"  {name:<32} {value:.6g}" if isinstance(value, float) else f"  {name:<32} {value}")
    else:
        for line in summary.get("failure_lines") or []:
            print(f"  {line}", file=sys.stderr)


def _follow(client, job_id: str, *, quiet: bool) -> dict:
    """Wait for the job with a progress bar (rich) fed by its event stream."""
    if quiet or not sys.stderr.isatty() and not _force_bar():
        last = [None]

        def line(ev):
            d = ev["data"]
            if not quiet and d["message"] != last[0]:
                last[0] = d["message"]
                print(f"{d['status']:<10} {d['progress'] * 100:5.1f}%  {d['message']}", file=sys.stderr)

        return client.wait(job_id, on_event=line)
    with progress_bar(job_id) as show:
        return client.wait(job_id, on_event=lambda ev: show(
            ev["data"]["progress"], f"{ev['data']['status']}: {ev['data']['message'][:50]}"))


@contextlib.contextmanager
def progress_bar(ident: str):
    """A rich progress bar for a job or a study, yielding ``show(fraction, message)``.  The bar goes to stderr
    so stdout stays the id and the numbers (a script can read them)."""
    from rich.console import Console
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    console = Console(stderr=True, force_terminal=_force_bar() or None)
    with Progress(TextColumn("{task.description}"), BarColumn(), TextColumn("{task.percentage:>5.1f}%"),
                  TimeElapsedColumn(), TextColumn("{task.fields[message]}"), console=console,
                  transient=False) as bar:
        task = bar.add_task(ident[:8], total=1.0, message="")
        yield lambda fraction, message: bar.update(task, completed=fraction, message=message)


def _force_bar() -> bool:
    import os

    return os.environ.get("TRAJLAB_PROGRESS") == "bar"


def _client(args):
    from app.cli.client import Client

    return Client(args.url)


def _read_submission(args) -> tuple[str, str | None, dict, str | None]:
    """(kind, preset, params, label) from the arguments and ``--file``.  The file may hold the parameters
    alone or a whole ``POST /v1/jobs`` body (it has ``kind``), as the examples/ files do; the command line
    wins over the body, and a kind that contradicts the body's is an error, not a silent choice."""
    body: dict = json.loads(Path(args.params).read_text()) if args.params else {}
    if not isinstance(body, dict):
        raise SystemExit(f"trajlab submit: {args.params} must hold a JSON object")
    if "kind" in body:
        if args.kind and args.kind != body["kind"]:
            raise SystemExit(f"trajlab submit: {args.params} is a {body['kind']!r} job, not {args.kind!r}")
        kind, preset, label, params = body["kind"], body.get("preset"), body.get("label"), body.get("params") or {}
    else:
        kind, preset, label, params = args.kind, None, None, body
    if not kind:
        raise SystemExit("trajlab submit: name the kind (or give --file with a whole job body)")
    return kind, args.preset or preset, params, args.label or label


def cmd_submit(args) -> int:
    from app.runtime.merge import deep_merge

    kind, preset, params, label = _read_submission(args)
    params = deep_merge(params, parse_set(args.set or []))
    client = _client(args)
    job = client.submit(kind, preset=preset, params=params or None, label=label)
    print(job["id"])
    if not args.wait:
        return 0
    job = _follow(client, job["id"], quiet=args.quiet)
    _print_job(job)
    _print_numbers(client, job)
    return EXIT[job["status"]]


def cmd_jobs(args) -> int:
    page = _client(args).jobs(kind=args.kind, status=args.status, limit=args.limit)
    for job in page["items"]:
        _print_job(job)
    print(f"{len(page['items'])} of {page['total']}", file=sys.stderr)
    return 0


def cmd_show(args) -> int:
    client = _client(args)
    job = client.job(args.id)
    print(json.dumps(job, indent=2))
    _print_numbers(client, job)
    return 0


def cmd_wait(args) -> int:
    client = _client(args)
    job = _follow(client, args.id, quiet=args.quiet)
    _print_job(job)
    _print_numbers(client, job)
    return EXIT[job["status"]]


def cmd_cancel(args) -> int:
    """Cancel, then wait for the job to stop: exit 3 once it is cancelled (0/1 if it finished first)."""
    client = _client(args)
    client.cancel(args.id)
    job = client.wait(args.id, timeout=args.timeout)
    _print_job(job)
    return EXIT[job["status"]]


def cmd_delete(args) -> int:
    client = _client(args)
    for job_id in args.ids:
        client.delete(job_id)
        print(f"{job_id}  deleted")
    return 0


def cmd_usage(args) -> int:
    u = _client(args).usage()
    cap = "no quota" if u["max_stored_bytes"] is None else f"quota {u['max_stored_bytes'] / 2**20:.1f} MiB"
    keep = "kept until deleted" if u["retention_days"] is None else f"deleted {u['retention_days']:g} days after finishing"
    print(f"{u['jobs']} jobs ({', '.join(f'{n} {s}' for s, n in u['jobs_by_status'].items()) or 'none'}); "
          f"{u['stored_bytes'] / 2**20:.2f} MiB stored, {cap}; finished jobs {keep}")
    return 0


def cmd_result(args) -> int:
    client = _client(args)
    result = None if args.csv else client.result(args.id)
    text = client.result_csv(args.id, args.csv) if args.csv else json.dumps(result, indent=2)
    if args.out:
        Path(args.out).write_text(text)
        if result is not None:  # stdout is free: what the answer says, as `wait` prints it
            for line in client.summary(args.id).get("headlines") or []:
                print(f"= {line['text']}")
    else:
        sys.stdout.write(text if text.endswith("\n") else text + "\n")
    return 0


def cmd_presets(args) -> int:
    """The named cases, by kind: name and the first line of the description; ``KIND`` narrows them."""
    presets = _client(args).presets()
    kinds = sorted({p["kind"] for p in presets})
    if args.kind and args.kind not in kinds:
        print(f"trajlab presets: no kind {args.kind!r}; the kinds: {', '.join(kinds)}", file=sys.stderr)
        return EXIT_BAD_INPUT
    for kind in [args.kind] if args.kind else kinds:
        print(kind)
        for p in presets:
            if p["kind"] == kind:
                first = (p.get("description") or "").strip().splitlines()
                print(f"  {p['name']:<40} {first[0][:80] if first else ''}")
    print(f"trajlab submit KIND --preset NAME [--set path=value ...] --wait; "
          f"a preset's parameters: {_client(args).url}/v1/presets/NAME", file=sys.stderr)
    return 0


def cmd_vehicles(args) -> int:
    """The named vehicles a reentry job may fly (``--set vehicle.preset=NAME``)."""
    vehicles = _client(args).vehicles()
    for v in vehicles:
        data, planet = v.get("vehicle") or {}, (v.get("planet") or {}).get("preset", "")
        first = (v.get("description") or "").strip().splitlines()
        print(f"{v['name']:<28} {planet:<6} {data.get('mass_kg', 0):>9.0f} kg {data.get('area_m2', 0):>7.2f} m2  "
              f"{first[0][:70] if first else ''}")
    print("fly one with: trajlab submit reentry --preset NAME --set vehicle.preset=VEHICLE", file=sys.stderr)
    return 0


def add_commands(sub) -> None:
    def common(p):
        p.add_argument("--url", help="trajlab service URL (TRAJLAB_URL; default http://127.0.0.1:8000)")
        p.set_defaults(run_client=True)
        return p

    p = common(sub.add_parser("submit", help="submit a job (add --wait to follow it with a progress bar)"))
    p.add_argument("kind", nargs="?", help="the job kind (optional when --file holds a whole job body)")
    p.add_argument("--preset")
    p.add_argument("--set", action="append", metavar="PATH=VALUE",
                   help="override one parameter, e.g. --set grid.intervals=50 (repeatable; JSON values)")
    p.add_argument("--params", "--file", dest="params", metavar="FILE",
                   help="a JSON file: the parameters (e.g. an ocp problem) or a whole job body with kind, preset, "
                        "params, as in examples/ (--set applies on top)")
    p.add_argument("--label")
    p.add_argument("--wait", action="store_true")
    p.add_argument("--quiet", action="store_true", help="no progress output")
    p.set_defaults(fn=cmd_submit)
    p = common(sub.add_parser("jobs", help="list jobs, newest first"))
    p.add_argument("--kind")
    p.add_argument("--status")
    p.add_argument("--limit", type=int, default=20)
    p.set_defaults(fn=cmd_jobs)
    for name, fn, help_ in (("show", cmd_show, "a job's document and key numbers"),
                            ("wait", cmd_wait, "follow a job to its end with a progress bar")):
        p = common(sub.add_parser(name, help=help_))
        p.add_argument("id")
        p.add_argument("--quiet", action="store_true")
        p.set_defaults(fn=fn)
    p = common(sub.add_parser("cancel", help="cancel a job and wait until it has stopped (exit 3)"))
    p.add_argument("id")
    p.add_argument("--timeout", type=float, default=120.0)
    p.set_defaults(fn=cmd_cancel)
    p = common(sub.add_parser("result", help="a succeeded job's result as JSON, or one table as CSV"))
    p.add_argument("id")
    p.add_argument("--csv", metavar="TABLE")
    p.add_argument("--out", metavar="FILE")
    p.set_defaults(fn=cmd_result)
    p = common(sub.add_parser("delete", help="delete jobs with their results (a running one is cancelled first)"))
    p.add_argument("ids", nargs="+", metavar="JOB_ID")
    p.set_defaults(fn=cmd_delete)
    p = common(sub.add_parser("usage", help="your jobs, the bytes they keep and the storage quota"))
    p.set_defaults(fn=cmd_usage)
    p = common(sub.add_parser("presets", help="the named cases of every kind (or of KIND) to submit with --preset"))
    p.add_argument("kind", nargs="?", help="only this kind's")
    p.set_defaults(fn=cmd_presets)
    p = common(sub.add_parser("vehicles", help="the named vehicles a reentry job may fly (vehicle.preset)"))
    p.set_defaults(fn=cmd_vehicles)


def run(args) -> int:
    """Run a client command; API errors become their one-line message and an exit code, never a traceback."""
    from app.cli.client import TrajlabError

    try:
        return args.fn(args)
    except TrajlabError as exc:
        print(f"trajlab: {exc.message}", file=sys.stderr)
        return EXIT_UNREACHABLE if exc.status_code == 0 else (1 if exc.status_code >= 500 else EXIT_BAD_INPUT)
    except (ValueError, OSError) as exc:
        print(f"trajlab: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        return 130
