"""Honest progress (issue 38 item 4): stages weighted by their measured cost, each round announced with
its number, never past 95% before the last stage starts, never going back.

The mechanism on its own (solvers.progress), then real jobs through their kind's ``run`` (as a worker
calls it): a refined ``ocp`` job, a ``reentry`` job refined to an accuracy, a robust ``ocp`` job (twin, robust
NLP, limit rounds, Monte Carlo, confirmation rounds) and an ``ocp`` job of several starts.
"""
from __future__ import annotations

import pytest

from app.kinds import KINDS, PRESETS
from app.service.params import resolve_params
from solvers.progress import CAP, Progress, ProgressMessage, Stage
from tests.preset_results import preset_progress, solve_preset
from tests.support import RecordingContext

PLAN = (Stage("build", 1.0), Stage("solve", 5.0), Stage("refinement", 3.0, rounds=True), Stage("answer", 1.0))


def _record():
    seen: list[tuple[float, ProgressMessage]] = []
    return seen, lambda f, m: seen.append((f, m))


def test_stages_follow_their_weights_and_rounds_halve_what_is_left():
    seen, sink = _record()
    p = Progress(sink, PLAN)
    p.stage("build")
    assert seen[-1][0] == 0.0 and seen[-1][1].stage == "build" and seen[-1][1].round is None
    p.stage("solve")(0.5, "IPOPT iteration 10")
    assert seen[-1][0] == pytest.approx(0.1 + 0.5 * 0.5)
    assert seen[-1][1] == "solve: IPOPT iteration 10"          # a str to every plain reader
    for k in (1, 2, 3):
        inner = p.within("refinement", (Stage("build", 1.0), Stage("solve", 1.0)), round=k)
        start = 0.6 + 0.3 * (1 - 0.5 ** (k - 1))
        assert seen[-1][0] == pytest.approx(start) and seen[-1][1].round == k
        inner.stage("solve")(1.0, "done")
        assert seen[-1][0] == pytest.approx(start + 0.3 * 0.5 ** k)
        assert seen[-1][1].stage == f"refinement round {k} / solve" and seen[-1][1].round == k
    assert max(f for f, _ in seen) < 0.9                       # rounds never use up their stage
    p.stage("answer")
    assert seen[-1][0] == pytest.approx(0.9)
    p.done("finished")
    assert seen[-1][0] == 1.0


def test_never_past_the_cap_before_the_last_stage_and_never_back():
    seen, sink = _record()
    p = Progress(sink, (Stage("solve", 99.0), Stage("answer", 1.0)))
    p.stage("solve")(1.0, "")
    assert seen[-1][0] == CAP                                  # 0.99 measured, 0.95 shown
    p.stage("solve")(0.0, "again")                             # a stage announced again: no step back
    assert seen[-1][0] == CAP
    p.stage("answer")(0.5, "")
    assert seen[-1][0] == pytest.approx(0.995)
    with pytest.raises(KeyError, match="not declared"):
        p.stage("monte carlo")


def _run(preset: str, overrides: dict):
    spec = KINDS[PRESETS[preset].kind]
    params = resolve_params(spec, PRESETS[preset].params, overrides)
    ctx = RecordingContext()
    out = spec.run(spec.params_model.model_validate(params), ctx)
    return out, ctx.messages


def _check_honest(messages) -> list[str]:
    """Monotone, under the cap until the last stage (``answer``) starts; returns the stages announced
    in order (consecutive repeats folded)."""
    fractions = [f for f, _ in messages]
    assert fractions == sorted(fractions), "progress went back"
    staged = [(f, m) for f, m in messages if isinstance(m, ProgressMessage)]
    first_answer = next(i for i, (_, m) in enumerate(staged) if m.stage == "answer")
    assert all(f <= CAP for f, _ in staged[:first_answer])
    assert staged[first_answer][0] >= staged[first_answer - 1][0]
    names: list[str] = []
    for _, m in staged:
        if not names or names[-1] != m.stage:
            names.append(m.stage)
    return names


def test_a_refined_ocp_job_announces_each_refinement_round():
    # the brachistochrone from 4 intervals to accuracy 1e-6 (benchmarks/ocp_refine.py's case)
    out, messages = _run("brachistochrone", {"accuracy": 1e-6, "transcription": {"intervals": 4}})
    assert out.status == "succeeded"
    assert out.result["objective"]["value"] == pytest.approx(1.8016, abs=1e-3)   # the published optimum
    names = _check_honest(messages)
    rounds = out.result["solver"]["refinement"]
    assert len(rounds) >= 2                                    # round 0 and at least one refinement
    for k in range(1, len(rounds)):
        # each round's own solve, or the accuracy check's solve on the round's mesh reused, then its check
        assert f"refinement round {k}" in names and f"refinement round {k} / check / solve" in names
    assert f"refinement round {len(rounds)}" not in names      # no round announced that did not run
    assert names[:4] == ["build", "solve", "verification", "check"] and names[-1] == "answer"


@pytest.mark.slow
def test_a_refined_reentry_job_announces_its_rounds_and_stays_under_the_cap():
    out, messages = _run("betts-max-crossrange", {"grid": {"intervals": 20}, "accuracy": 1e-4})
    assert out.status == "succeeded"
    assert out.result["objective"]["value"] == pytest.approx(34.14, abs=0.05)   # Betts' 34.1412 deg
    names = _check_honest(messages)
    rounds = out.result["solver"].get("refinement") or []
    assert len(rounds) >= 2
    for k in range(1, len(rounds)):
        assert f"refinement round {k}" in names and f"refinement round {k} / verification" in names
    limit_rounds = [s["stage"] for s in out.result["solver"]["stages"] if s["stage"].startswith("limit round")]
    for k in range(1, len(limit_rounds) + 1):
        assert any(n.endswith(f"limit round {k}") for n in names)
    assert names[0] == "solve" and names[-1] == "answer"


def test_the_worker_stores_the_stage_and_the_job_document_shows_it(sqlite_db):
    """The stage of a ProgressMessage reaches the job row through the worker's heartbeat and the API's
    job document; a message of no declared stage clears it (a stale stage would be a lie)."""
    import time

    from app.runtime.settings import Settings
    from app.service import jobs
    from app.service.job_document import job_to_dict
    from worker.context import WorkerJobContext

    job, _ = jobs.create_job(sqlite_db, kind="ocp", params={}, label=None, preset=None)
    claim = jobs.claim(sqlite_db, job.id, 1, worker="w", max_attempts=3, stale_after_s=60)
    ctx = WorkerJobContext(sqlite_db, claim, settings=Settings(heartbeat_interval_s=0.05))

    def wait_for(stage):
        deadline = time.monotonic() + 30
        while (doc := job_to_dict(jobs.get_job(sqlite_db, job.id)))["stage"] != stage:
            assert time.monotonic() < deadline, doc
            time.sleep(0.02)
        return doc

    with ctx:
        p = Progress(ctx.progress, PLAN)
        inner = p.within("refinement", (Stage("solve", 1.0),), round=2)
        inner.stage("solve")(0.5, "IPOPT iteration 7")
        doc = wait_for({"name": "refinement round 2 / solve", "round": 2})
        assert doc["message"] == "refinement round 2 / solve: IPOPT iteration 7"
        assert 0.6 < doc["progress"] <= CAP
        ctx.progress(0.97, "done: Solve_Succeeded")
        wait_for(None)


@pytest.mark.slow
def test_a_robust_ocp_job_declares_its_stages():
    # rocket-ascent-q-limit-robust: the twin, the robust NLP, a limit round, the Monte Carlo (2000 samples)
    # and, as measured, one confirmation round (the constraints' k raised).  The preset's own run, as _run
    # makes it (no overrides), shared with the plots and robust-preset tests (tests/preset_results.py)
    _, _, out = solve_preset("rocket-ascent-q-limit-robust", {})
    messages = preset_progress("rocket-ascent-q-limit-robust", {})
    assert out.status == "succeeded" and out.result["robust"]["confirmed"]
    names = _check_honest(messages)
    assert not [m for _, m in messages if not isinstance(m, ProgressMessage)]   # every message names its stage
    assert names[0].startswith("deterministic twin") and names[-1] == "answer"
    for stage in ("robust build", "robust solve", "monte carlo"):
        assert stage in names
    rounds = out.result["robust"]["rounds"]
    for r in range(1, len(rounds)):
        assert f"confirmation round {r} / monte carlo" in names
    assert f"confirmation round {len(rounds)}" not in " ".join(names)   # no round announced that did not run
    assert max(f for f, m in messages if m.stage != "answer") <= CAP


@pytest.mark.slow
def test_a_search_job_declares_its_starts_and_judges_last():
    # four starts of the brachistochrone, one after the other in this process (each a piece)
    out, messages = _run("brachistochrone", {"search": {"starts": 4}})
    assert out.status == "succeeded" and out.result["search"]["succeeded"] == 4
    names = _check_honest(messages)
    assert names == ["starts", "answer"]
    done = [f for f, m in messages if m.stage == "starts" and "done" in m]
    assert len(done) == 4 and done == sorted(done) and done[-1] <= CAP   # each start moves the bar, never past 95%
    assert done[0] == pytest.approx(0.25 * 99.99 / 100, abs=1e-3)
