"""Midcourse-correction timing (paper 002): Table 3, the GA plumbing, Monte Carlo."""
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from solvers.astro.j2 import LaunchFrame
from solvers.common import Outcome
import solvers.midcourse as midcourse
from solvers.midcourse import cases
from solvers.midcourse import (
    CorrectionEvaluator,
    Dispersion,
    GASettings,
    MidcourseProblem,
    repair_schedule,
    solve,
)

FRAME = cases.paper_frame()


def paper_problem(**kw) -> MidcourseProblem:
    """Paper 002 Tables 1-2 in the spec's fitted launch frame."""
    return midcourse.paper_problem(**kw)


# Spec midcourse.md, Table 3, "reimpl." columns: (times, dV m/s, position error m, velocity error m/s).
TABLE3 = [
    ([], 0.0, 708233.0, 103.455),
    ([6000], 91.798, 786.7, 32.349),
    ([8000], 138.097, 330.1, 68.053),
    ([3000, 8000], 51.518, 337.6, 8.866),
    ([1000, 8000], 32.004, 337.5, 4.315),
    ([2000, 5000, 8000], 40.160, 337.8, 4.623),
    ([1000, 5000, 8000], 29.072, 337.8, 2.081),
]
# Paper 002 Table 3 itself: dV and velocity error agree with it to 0.5 m/s too.
PAPER_DV_VEL = [(0.0, 103.444), (91.796, 32.344), (138.049, 68.000), (51.293, 8.955),
                (32.077, 4.422), (40.618, 5.023), (29.242, 2.523)]


@pytest.fixture(scope="module")
def table3_solution():
    return solve(paper_problem(mode="evaluate", schedules=[row[0] for row in TABLE3]))


@pytest.mark.slow
def test_table3_matches_reimplementation(table3_solution):
    sol = table3_solution
    assert sol.status.outcome is Outcome.OPTIMAL
    assert sol.lambert_failures == 0
    assert len(sol.schedules) == len(TABLE3)
    for res, (times, dv, pos, vel) in zip(sol.schedules, TABLE3):
        assert list(res.times) == times
        assert res.objectives[0] == pytest.approx(dv, abs=0.5), times
        assert res.objectives[2] == pytest.approx(vel, abs=0.5), times
        # The reimplementation column is given to 0.1 m; allow 2 m (0.6% of 330 m).
        assert res.objectives[1] == pytest.approx(pos, abs=2.0), times


def test_table3_delta_v_and_velocity_error_match_the_paper(table3_solution):
    # Spec midcourse.md: the paper's own dV and velocity errors to within 0.5 m/s (its 3-correction
    # rows differ by up to 0.46 m/s); position errors do not match (about 337 m vs 261 m).
    for res, (dv, vel) in zip(table3_solution.schedules, PAPER_DV_VEL):
        assert res.objectives[0] == pytest.approx(dv, abs=0.5)
        assert res.objectives[2] == pytest.approx(vel, abs=0.5)


def test_error_free_nominal_hits_target(table3_solution):
    miss_r, miss_v = table3_solution.nominal_miss
    assert miss_r < 3.0 and miss_v < 0.02


def test_impulses_sum_to_reported_delta_v(table3_solution):
    for res in table3_solution.schedules[1:]:
        assert res.impulses.shape == (len(res.times), 3)
        assert np.sum(np.linalg.norm(res.impulses, axis=1)) == pytest.approx(res.objectives[0], rel=1e-12)


def test_eci_input_gives_the_same_objectives():
    # Rotate the paper problem into an Earth-centred frame with the spin axis along z.
    w = FRAME.spin_axis
    e1 = np.cross(w, [1.0, 0.0, 0.0])
    e1 /= np.linalg.norm(e1)
    rot = np.vstack([e1, np.cross(w, e1), w])       # launch axes -> ECI axes
    base = paper_problem()
    eci = replace(base, r0=rot @ (base.r0 + FRAME.r0), v0=rot @ base.v0,
                  r_target=rot @ (base.r_target + FRAME.r0), v_target=rot @ base.v_target,
                  position_error=rot @ base.position_error, velocity_error=rot @ base.velocity_error,
                  frame=LaunchFrame.eci())
    x = np.array([[1000.0, 8000.0], [3000.0, 8000.0], [500.0, 12000.0]])
    f_launch = CorrectionEvaluator(base)(x)
    f_eci = CorrectionEvaluator(eci)(x)
    assert np.allclose(f_launch[:, [0, 2]], f_eci[:, [0, 2]], atol=1e-6)
    assert np.allclose(f_launch[:, 1], f_eci[:, 1], atol=1e-2)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.floats(-1000.0, 14000.0), min_size=1, max_size=5), st.floats(0.0, 2000.0))
def test_repair_sorts_spaces_and_bounds(times, spacing):
    lo, hi = 0.0, 12800.0
    x = repair_schedule(np.array([times]), lower=lo, upper=hi, spacing=spacing)[0]
    assert np.all(x >= lo - 1e-9) and np.all(x <= hi + 1e-9)
    assert np.all(np.diff(x) >= spacing - 1e-6)
    assert np.array_equal(repair_schedule(x[None], lower=lo, upper=hi, spacing=spacing)[0], x)


def test_repair_examples():
    x = repair_schedule(np.array([[9000.0, 100.0], [5000.0, 5010.0], [12790.0, 12800.0], [-5.0, 13000.0]]),
                        lower=0.0, upper=12800.0, spacing=100.0)
    assert np.array_equal(x, [[100.0, 9000.0], [5000.0, 5100.0], [12700.0, 12800.0], [0.0, 12800.0]])


def small_run(**kw):
    ga = GASettings(population=20, generations=20)
    return paper_problem(mode="optimize", corrections=2, ga=ga, **kw)


def _nondominated(f):
    return all(not np.any(np.all(f <= fi, axis=1) & np.any(f < fi, axis=1)) for fi in f)


def test_small_run_is_reproducible_and_its_front_is_nondominated():
    messages = []
    a = solve(small_run(), seed=7, on_progress=lambda frac, msg: messages.append((frac, msg)))
    b = solve(small_run(), seed=7)
    assert a.status.outcome is Outcome.OPTIMAL and b.status.outcome is Outcome.OPTIMAL
    assert a.generations == 20 and a.seed == 7
    assert np.array_equal(a.pareto_times, b.pareto_times)
    assert np.array_equal(a.pareto_objectives, b.pareto_objectives)
    assert len(a.pareto_times) >= 3 and _nondominated(a.pareto_objectives)
    assert np.all(np.diff(a.pareto_times, axis=1) >= 0.0)
    assert 0.0 < a.hypervolume <= 1.0
    # The front's objectives are those of its times.
    assert np.allclose(CorrectionEvaluator(small_run())(a.pareto_times), a.pareto_objectives, rtol=1e-9)
    assert messages[-1] == (1.0, "generation 20/20")
    assert all(f1 <= f2 for (f1, _), (f2, _) in zip(messages, messages[1:]))
    c = solve(small_run(), seed=8)
    assert not np.array_equal(a.pareto_times, c.pareto_times)


def test_spacing_is_honoured_on_the_front():
    sol = solve(small_run(min_spacing=3000.0, time_bounds=(0.0, 12000.0)), seed=3)
    assert sol.status.outcome is Outcome.OPTIMAL
    assert np.all(np.diff(sol.pareto_times, axis=1) >= 3000.0 - 1e-6)
    assert np.all(sol.pareto_times >= 0.0) and np.all(sol.pareto_times <= 12000.0)


def test_cancellation_returns_a_partial_front():
    calls = {"n": 0}

    def stop():
        calls["n"] += 1
        return calls["n"] >= 3

    sol = solve(small_run(), seed=1, should_stop=stop)
    assert sol.status.outcome is Outcome.CANCELLED
    assert sol.generations == 3
    assert len(sol.pareto_times) >= 1 and _nondominated(sol.pareto_objectives)


def test_late_single_correction_beats_early_one_on_position():
    # Spec: in this model the position error keeps falling as the last correction moves later.
    f = CorrectionEvaluator(paper_problem())(np.array([[6000.0], [8000.0], [10000.0], [12000.0]]))
    assert np.all(np.diff(f[:, 1]) < 0.0)


def test_monte_carlo_is_the_per_sample_evaluation():
    disp = Dispersion(samples=6, percentile=90.0, seed=4)
    prob = paper_problem(dispersion=disp)
    ev = CorrectionEvaluator(prob)
    x = np.array([[1000.0, 8000.0], [3000.0, 8000.0]])
    per_sample = ev.evaluate_samples(x)
    assert per_sample.shape == (2, 6, 3)
    offsets = ev.initial - np.r_[prob.r0 + FRAME.r0, prob.v0]
    for s in (0, 5):
        single = CorrectionEvaluator(paper_problem(position_error=offsets[s, :3],
                                                   velocity_error=offsets[s, 3:]))(x)
        assert np.allclose(single, per_sample[:, s], rtol=1e-9, atol=1e-6)
    obj, mean, pct = ev.statistics(per_sample)
    assert np.allclose(mean, per_sample.mean(axis=1))
    assert np.array_equal(obj, pct)
    assert np.all(pct >= np.min(per_sample, axis=1)) and np.all(pct <= np.max(per_sample, axis=1))


@pytest.mark.slow
def test_monte_carlo_statistics_and_seed():
    def run(statistic, seed):
        disp = Dispersion(samples=200, percentile=99.0, seed=seed, statistic=statistic)
        return solve(paper_problem(mode="evaluate", schedules=[[1000.0, 8000.0]], dispersion=disp))

    a, b, c = run("percentile", 1), run("mean", 1), run("percentile", 2)
    assert a.status.outcome is Outcome.OPTIMAL
    ra, rb, rc = a.schedules[0], b.schedules[0], c.schedules[0]
    assert np.all(ra.percentile > ra.mean)
    assert np.array_equal(ra.objectives, ra.percentile) and np.array_equal(rb.objectives, rb.mean)
    assert np.array_equal(ra.mean, rb.mean)                  # same seed, same samples
    assert not np.array_equal(ra.mean, rc.mean)
    # The correction is nearly linear in the initial error: the fixed 3-sigma corner costs
    # 32.0 m/s, so Gaussian errors with that 3-sigma per axis must cost less on average.
    assert 3.0 < ra.mean[0] < 32.0


def test_mirrored_branch_solve_equals_two_explicit_lambert_calls():
    from solvers.astro.lambert import lambert

    ev = CorrectionEvaluator(paper_problem())
    rng = np.random.default_rng(5)
    t = rng.uniform(0.0, 12800.0, 40)
    states = ev._dense[0](t)
    # Perturb the velocity so that some cases prefer each branch.
    states[:, 3:] *= rng.choice([1.0, -1.0], size=(40, 1))
    dv, ok = ev._impulse(states[:, :3], states[:, 3:], 12900.0 - t)
    target = np.broadcast_to(ev.r_target, (40, 3))
    cand = np.stack([lambert(ev.mu, states[:, :3], target, 12900.0 - t, prograde=p).v1 - states[:, 3:]
                     for p in (True, False)])
    pick = np.argmin(np.linalg.norm(cand, axis=2), axis=0)
    assert ok.all() and len(set(pick)) == 2
    assert np.allclose(dv, cand[pick, np.arange(40)], rtol=0, atol=1e-6)


def test_array_nsga2_ranks_and_crowding_match_their_definitions():
    from solvers.midcourse.nsga2 import crowding, nondominated_ranks, survive

    rng = np.random.default_rng(4)
    f = np.round(rng.uniform(0, 10, (60, 3)), 0)          # coarse values: ties and exact copies occur
    f[5] = f[7]
    rank = nondominated_ranks(f)
    # brute force: front 0 is the non-dominated set; front r the non-dominated set of what is left
    left = np.arange(len(f))
    r = 0
    while left.size:
        sub = f[left]
        dominated = np.array([np.any(np.all(sub <= s, axis=1) & np.any(sub < s, axis=1)) for s in sub])
        assert set(np.flatnonzero(rank == r)) == set(left[~dominated])
        left = left[dominated]
        r += 1
    crowd = crowding(f, rank)
    assert crowd[7] == 0.0 or crowd[5] == 0.0              # one of two copies carries no spread
    for r in np.unique(rank):
        idx = np.flatnonzero(rank == r)
        for j in range(3):                                  # a front's extremes are kept first
            assert np.isinf(crowd[idx[np.argmin(f[idx, j])]]) or np.any(f[idx, j] == f[idx, j].min())
    keep, kr, kc = survive(f, 25)
    assert len(keep) == 25 and np.all(np.diff(kr) >= 0)
    worst = kr.max()
    assert set(np.flatnonzero(rank < worst)) <= set(keep)   # whole better fronts survive
    assert kc[kr == worst].min() >= crowd[(rank == worst) & ~np.isin(np.arange(60), keep)].max(initial=0.0)
