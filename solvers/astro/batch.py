"""Broadcasting of (3,)/(N, 3) vectors against scalar/(N,) times: the batch shape of astro/."""
from __future__ import annotations

import numpy as np


def broadcast_pair(a, b, t) -> tuple[np.ndarray, np.ndarray, np.ndarray, bool]:
    """``(a (N,3), b (N,3), t (N,), single)``; ``single`` when all inputs were one case,
    so callers can hand back (3,) vectors for (3,) inputs."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    t = np.asarray(t, dtype=float)
    single = a.ndim == 1 and b.ndim == 1 and t.ndim == 0
    a2, b2 = np.atleast_2d(a), np.atleast_2d(b)
    n = max(a2.shape[0], b2.shape[0], t.size if t.ndim else 1)
    return (np.broadcast_to(a2, (n, 3)), np.broadcast_to(b2, (n, 3)),
            np.broadcast_to(np.atleast_1d(t), (n,)).astype(float), single)
