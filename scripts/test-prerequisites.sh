#!/usr/bin/env bash
# What the test suite needs beyond the Python packages, made present or named: the machine's
# PostgreSQL (127.0.0.1:5432) and Redis (127.0.0.1:6379) running, and Debian's Chromium for the
# browser tests (Playwright cannot download its own browser here), and Debian's prometheus (prometheus,
# promtool) for the metrics tests.  `make test` and `.ci/run`
# both go through this script, so the README's `make test` is the whole set-up on a fresh machine.
# A part that cannot be made present stops the run with one line naming it and how to get it:
# the suite never skips a test for a missing tool.
set -uo pipefail

fail() { echo "make test: $1" >&2; exit 1; }

as_root() {
  if [ "$(id -u)" = 0 ]; then "$@"; elif command -v sudo >/dev/null 2>&1; then sudo -n "$@"; else return 1; fi
}

if [ -z "${TRAJLAB_TEST_PG_ADMIN:-}" ] && ! pg_isready -h 127.0.0.1 -p 5432 -q 2>/dev/null; then
  if [ -d /etc/postgresql ]; then
    as_root pg_ctlcluster --skip-systemctl-redirect "$(ls /etc/postgresql | head -1)" main start >/dev/null 2>&1
    for _ in $(seq 30); do pg_isready -h 127.0.0.1 -p 5432 -q && break; sleep 1; done
  fi
  pg_isready -h 127.0.0.1 -p 5432 -q 2>/dev/null \
    || fail "PostgreSQL is not reachable on 127.0.0.1:5432 (install Debian's postgresql, trust auth for 127.0.0.1, a database 'test'), or set TRAJLAB_TEST_PG_ADMIN"
fi

if [ -z "${TRAJLAB_TEST_REDIS:-}" ] && ! redis-cli -h 127.0.0.1 -p 6379 ping >/dev/null 2>&1; then
  if command -v redis-server >/dev/null 2>&1; then
    mkdir -p /var/lib/redis /var/log/redis 2>/dev/null
    redis-server --daemonize yes --bind 127.0.0.1 -::1 --port 6379 --save "" --appendonly no \
      --dir /var/lib/redis --logfile /var/log/redis/ci.log >/dev/null 2>&1
    for _ in $(seq 30); do redis-cli -h 127.0.0.1 -p 6379 ping >/dev/null 2>&1 && break; sleep 1; done
  fi
  redis-cli -h 127.0.0.1 -p 6379 ping >/dev/null 2>&1 \
    || fail "Redis is not reachable on 127.0.0.1:6379 (apt-get install redis-server), or set TRAJLAB_TEST_REDIS"
fi

if ! command -v chromium >/dev/null 2>&1; then
  echo "make test: installing Debian's chromium for the browser tests (apt-get install chromium)" >&2
  { as_root apt-get update -q && DEBIAN_FRONTEND=noninteractive as_root apt-get install -y -q chromium; } >/dev/null 2>&1
  command -v chromium >/dev/null 2>&1 \
    || fail "Chromium is missing and could not be installed; run 'sudo apt-get install chromium' (the browser tests drive /usr/bin/chromium)"
fi
if ! command -v prometheus >/dev/null 2>&1 || ! command -v promtool >/dev/null 2>&1; then
  echo "make test: installing Debian's prometheus for the metrics tests (apt-get install prometheus)" >&2
  { as_root apt-get update -q && DEBIAN_FRONTEND=noninteractive as_root apt-get install -y -q prometheus; } >/dev/null 2>&1
  command -v prometheus >/dev/null 2>&1 && command -v promtool >/dev/null 2>&1 \
    || fail "Prometheus is missing and could not be installed; run 'sudo apt-get install prometheus' (the metrics tests start /usr/bin/prometheus and run promtool)"
fi
exit 0
