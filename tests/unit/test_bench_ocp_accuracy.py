"""The accuracy benchmark's measure (benchmarks.ocp_accuracy): the objective error against a published optimum
is floored at that optimum's own precision, half a unit of its last printed digit."""
from __future__ import annotations

import pytest

from benchmarks.ocp_accuracy import objective_error, precision


def test_the_error_is_relative_and_floored_at_the_published_digits():
    assert precision(960.2285) == pytest.approx(0.5e-4 / 960.2285)
    assert precision(4.0) == pytest.approx(0.5e-1 / 4.0)
    assert precision(4.0, "bryson-denham") < 1e-14       # 4 / (9 l): exact, however it is printed
    assert objective_error("bryson-denham", 4.0 + 4e-9) == pytest.approx(1e-9)
    # 960.2285 kg is the lunar lander's closed form to 7 digits: 1e-9 kg off cannot be told from zero
    assert objective_error("lunar-lander-bang-bang", 960.2285 + 1e-9) == pytest.approx(precision(960.2285))
    assert objective_error("lunar-lander-bang-bang", 960.2285 - 0.5) == pytest.approx(0.5 / 960.2285)
