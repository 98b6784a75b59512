"""Small filesystems for the full-disk fault tests: a size-limited tmpfs mounted (as root) for the test and
unmounted after it, and a filler file that takes every byte left and gives them back when removed."""
from __future__ import annotations

import errno
import os
import shutil
import subprocess
import tempfile
import threading
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

import pytest


@contextmanager
def tmpfs(size_mb: int, *, owner: str | None = None) -> Iterator[Path]:
    """A tmpfs of ``size_mb`` mounted on a new directory under the system's temp directory (which the
    ``postgres`` user can reach, unlike pytest's 0700 ones), owned by ``owner``; unmounted and removed after."""
    if os.geteuid() != 0:
        pytest.fail("the full-disk fault tests mount a size-limited tmpfs and must run as root (CI does: "
                    "sudo make test-faults); they are never skipped")
    path = Path(tempfile.mkdtemp(prefix="trajlab-disk-"))
    subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size_mb}m,mode=0755", "tmpfs", str(path)],
                   check=True, capture_output=True, timeout=30)
    try:
        if owner is not None:
            shutil.chown(path, owner, owner)
        yield path
    finally:
        # lazy: a server that still holds a file open must not keep the mount (or the test) alive
        subprocess.run(["umount", "--lazy", str(path)], capture_output=True, timeout=30)
        shutil.rmtree(path, ignore_errors=True)


def free_mb(path: Path) -> float:
    st = os.statvfs(path)
    return st.f_bavail * st.f_frsize / 2**20


class Filler:
    """Fills the filesystem of ``path`` to the last block and keeps it full (a server that frees a file
    meanwhile does not get the space back) until :meth:`free` removes the filler."""

    def __init__(self, path: Path):
        self.file = path / "filler"
        self.bytes = 0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def _top_up(self) -> None:
        chunk = 1 << 20
        with open(self.file, "ab", buffering=0) as f:  # unbuffered: a short write is counted, never retried
            while chunk >= 512:
                try:
                    self.bytes += f.write(b"\0" * chunk)
                except OSError as exc:
                    if exc.errno != errno.ENOSPC:
                        raise
                    chunk //= 4

    def fill(self) -> "Filler":
        self._top_up()
        self._thread = threading.Thread(target=self._keep_full, daemon=True)
        self._thread.start()
        return self

    def _keep_full(self) -> None:
        while not self._stop.wait(0.2):
            self._top_up()

    def free(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=10)
        self.file.unlink(missing_ok=True)
