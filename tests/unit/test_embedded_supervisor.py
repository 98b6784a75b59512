"""The embedded supervisor's backoff: doubling through a crash loop, back to the start after a healthy period
(a fake clock for the rule, a real short-lived child for the supervisor that applies it), and the embedded
Redis started so that a failed dump does not refuse writes."""
from __future__ import annotations

import time

from app.runtime.embedded import Backoff, Supervised, redis_command


def test_backoff_doubles_through_a_crash_loop_up_to_its_cap():
    b = Backoff(initial_s=0.5, max_s=30.0, healthy_after_s=60.0)
    assert [b.delay(up_s=1.0) for _ in range(8)] == [0.5, 1.0, 2.0, 4.0, 8.0, 16.0, 30.0, 30.0]


def test_backoff_starts_again_after_a_healthy_period():
    b = Backoff(initial_s=0.5, max_s=30.0, healthy_after_s=60.0)
    for _ in range(7):
        b.delay(up_s=0.2)  # a crash loop: the next wait is 30 s
    assert b.delay(up_s=59.9) == 30.0  # not healthy long enough
    assert b.delay(up_s=60.0) == 0.5  # an hour of service later: restarted at once
    assert b.delay(up_s=0.1) == 1.0  # and a new loop doubles from there


def _supervise(tmp_path, cmd: list[str], backoff: Backoff, restarts: int, timeout: float = 20.0) -> list[float]:
    child = Supervised("child", cmd, env={}, log_path=tmp_path / "child.log", backoff=backoff).start()
    try:
        deadline = time.monotonic() + timeout
        while child.restarts < restarts:
            assert time.monotonic() < deadline, f"only {child.restarts} restarts in {timeout} s"
            time.sleep(0.05)
        return list(child.delays[:restarts])
    finally:
        child.stop(timeout=5)


def test_a_real_child_that_crashes_at_once_waits_longer_each_time(tmp_path):
    # healthy only after 5 s: an exit at once is never mistaken for one, however late the poll sees it
    delays = _supervise(tmp_path, ["/bin/sh", "-c", "exit 3"],
                        Backoff(initial_s=0.1, max_s=10.0, healthy_after_s=5.0), restarts=3)
    assert delays == [0.1, 0.2, 0.4]


def test_a_real_child_that_ran_healthy_is_restarted_without_the_loops_wait(tmp_path):
    # up 0.8 s each time (healthy after 0.6 s): every restart waits the initial 0.1 s, never 0.2, 0.4
    delays = _supervise(tmp_path, ["/bin/sh", "-c", "sleep 0.8; exit 3"],
                        Backoff(initial_s=0.1, max_s=10.0, healthy_after_s=0.6), restarts=3)
    assert delays == [0.1, 0.1, 0.1]


def test_embedded_redis_keeps_accepting_writes_when_a_dump_fails(tmp_path):
    cmd = redis_command(tmp_path)
    assert cmd[cmd.index("--stop-writes-on-bgsave-error") + 1] == "no"


def test_embedded_redis_stops_when_its_dump_cannot_be_written(tmp_path):
    import os
    import subprocess

    import redis

    from app.runtime.embedded import redis_shutdown, wait_for_socket

    proc = subprocess.Popen(redis_command(tmp_path), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        wait_for_socket(tmp_path / "redis.socket")
        client = redis.Redis(unix_socket_path=str(tmp_path / "redis.socket"))
        client.set("k", "v")
        gone = tmp_path / "gone"
        gone.mkdir()
        client.config_set("dir", str(gone))
        os.rmdir(gone)  # the dump's directory vanishes: SHUTDOWN SAVE fails, as on a full disk
        assert redis_shutdown(tmp_path / "redis.socket", timeout=5)
        assert proc.wait(timeout=10) is not None
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
