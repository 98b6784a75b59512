"""The registry's public function (``app.kinds.register_kind``) and the shared code asking what it registered:
a kind declared here, in this process, is costed, queued, refused for memory, tabled and thinned by its own
KindSpec, with no table anywhere naming it (the HTTP path, API and worker: tests/integration/test_throwaway_kind.py)."""
from __future__ import annotations

import pytest

from app.kinds import KINDS, PRESETS, register_kind
from app.kinds.base import KindSpec, MemoryModel, Preset, RunOutcome, StrictModel
from app.results.compact import compact
from app.results.tables import columns_at, tables_for
from app.runtime.settings import Settings
from app.service import job_memory, quota
from app.service.broker import QUEUE_HEAVY, QUEUE_JOBS
from app.service.summary import WARM_START_FIELD


class ScratchParams(StrictModel):
    size: int = 10


def _spec(name: str = "scratch_kind", **fields) -> KindSpec:
    return KindSpec(kind=name, params_model=ScratchParams, run=lambda p, ctx: RunOutcome("succeeded", result={}),
                    cost=lambda p: 2.0 * p["size"],
                    memory=MemoryModel(floor_mb=100.0, size=lambda p: float(p["size"]), floor_size=10.0,
                                       per_unit_mb=0.5, grows_with="size"),
                    tables={"trajectory": columns_at("trajectory")},
                    compact=lambda r, include: r if "all" in include else {"short": True},
                    presets=[Preset(f"{name}-preset", name, "a preset", {})], **fields)


@pytest.fixture
def registered():
    """Register kinds for one test and forget them after it (the registry is this process's)."""
    names = []

    def add(spec: KindSpec) -> KindSpec:
        names.append(spec.kind)
        return register_kind(spec)

    yield add
    for name in names:
        spec = KINDS.pop(name, None)
        for p in spec.presets if spec is not None else []:
            PRESETS.pop(p.name, None)


def test_the_shared_code_asks_a_kind_registered_at_run_time(registered):
    spec = registered(_spec(always_heavy=False, warm_start_field="initial_guess.from_job"))
    settings = Settings(database_url="sqlite://", job_memory_mb=200, heavy_cost=100.0)
    assert PRESETS["scratch_kind-preset"].kind == spec.kind
    assert quota.estimate_cost(spec.kind, {"size": 30}) == 60.0
    assert quota.queue_for(spec.kind, 60.0, settings) == QUEUE_JOBS
    assert quota.queue_for(spec.kind, 120.0, settings) == QUEUE_HEAVY
    assert job_memory.estimate_mb(spec.kind, {"size": 30}) == pytest.approx(0.9 * (100.0 + 0.5 * 20))
    job_memory.check(spec.kind, {"size": 100}, settings)   # 0.9 x 145 MB: under the cap
    with pytest.raises(job_memory.OverMemoryCap, match=r"grows with size.*TRAJLAB_JOB_MEMORY_MB"):
        job_memory.check(spec.kind, {"size": 1000}, settings)
    result = {"trajectory": {"t_s": [0.0, 1.0], "x_m": [2.0, 3.0]}}
    assert tables_for(spec.kind, result) == {"trajectory": result["trajectory"]}
    assert compact(spec.kind, result, set()) == {"short": True} and compact(spec.kind, result, {"all"}) is result
    assert WARM_START_FIELD.get(spec.kind) == "initial_guess.from_job"


def test_always_heavy_goes_to_the_heavy_queue_whatever_its_cost(registered):
    spec = registered(_spec("scratch_heavy", always_heavy=True))
    assert quota.queue_for(spec.kind, 0.0, Settings(database_url="sqlite://")) == QUEUE_HEAVY


def test_a_kind_or_preset_name_is_declared_once(registered):
    registered(_spec())
    with pytest.raises(ValueError, match="already registered"):
        register_kind(_spec())
    with pytest.raises(ValueError, match="taken by other kinds"):
        register_kind(KindSpec(kind="scratch_other", params_model=ScratchParams, run=lambda p, ctx: None,
                               cost=lambda p: 1.0, memory=MemoryModel(floor_mb=1.0),
                               presets=[Preset("scratch_kind-preset", "scratch_other", "", {})]))
    assert "scratch_other" not in KINDS


def test_cost_and_memory_have_no_default():
    with pytest.raises(TypeError, match="cost|memory"):
        KindSpec(kind="scratch_bare", params_model=ScratchParams, run=lambda p, ctx: None)
