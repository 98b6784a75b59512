"""Serving a result body: the typed path of ``GET /v1/jobs/{id}/result`` against the untyped one.

Run: ``python -m benchmarks.result_body``.  Solves the intercept preset (both methods, porkchop on)
and the robust preset (2,000 Monte Carlo samples: the stored body is as large as with 10,000, the
traces and terminal samples are capped), then times three ways of answering a GET with the same
compact or full body through FastAPI's whole stack (TestClient, best of ``REPEATS``):

- baseline: ``JSONResponse(body)``, Starlette's ``json.dumps`` (how the route answered before the
  typed models);
- ``result_json``: the route's way now, the kind's model validates the body and pydantic-core writes
  it (:func:`app.api.result_body.result_json`);
- ``response_model``: FastAPI validating and serializing the returned dict itself against the union.

Each figure is a ratio to the baseline measured in the same run.  The machine is shared: take the
ratios, not the milliseconds.
"""
from __future__ import annotations

import time

from fastapi import FastAPI, Response
from fastapi.responses import JSONResponse
from fastapi.testclient import TestClient

from app.kinds import KINDS, PRESETS
from app.kinds.base import InProcessContext
from app.service.params import resolve_params
from app.results.compact import compact
from app.api.result_body import JobResult, result_json

REPEATS = 9
CASES = {"long-range-intercept": {"porkchop": {"enabled": True}},
         "robust-max-crossrange": {"monte_carlo": {"samples": 2000}}}




def _solve(name: str, overrides: dict) -> tuple[str, dict]:
    preset = PRESETS[name]
    spec = KINDS[preset.kind]
    params = resolve_params(spec, preset.params, overrides)
    outcome = spec.run(spec.params_model.model_validate(params), InProcessContext())
    assert outcome.status == "succeeded", outcome.error
    return preset.kind, outcome.result


def _app(results: dict[str, tuple[str, dict]]) -> FastAPI:
    app = FastAPI()

    def body(name: str, full: bool) -> tuple[str, dict]:
        kind, result = results[name]
        return kind, compact(kind, result, {"scan", "samples"} if full else set())

    @app.get("/baseline/{name}")
    def baseline(name: str, full: bool = False):
        return JSONResponse(body(name, full)[1])

    @app.get("/result_json/{name}")
    def typed(name: str, full: bool = False):
        return Response(result_json(*body(name, full)), media_type="application/json")

    @app.get("/response_model/{name}", response_model=JobResult, response_model_exclude_unset=True)
    def fastapi_typed(name: str, full: bool = False):
        return body(name, full)[1]

    return app


def main() -> None:
    from benchmarks.results import write_results

    results = {name: _solve(name, overrides) for name, overrides in CASES.items()}
    client = TestClient(_app(results))
    figures: dict = {}
    print(f"{'result':<24}{'body':<9}{'kB':>8}{'baseline ms':>13}{'result_json':>13}{'ratio':>7}"
          f"{'response_model':>16}{'ratio':>7}")
    for name in CASES:
        for full in (False, True):
            best = {}
            for way in ("baseline", "result_json", "response_model"):
                times = []
                for _ in range(REPEATS):
                    t = time.perf_counter()
                    r = client.get(f"/{way}/{name}", params={"full": full})
                    times.append(time.perf_counter() - t)
                    assert r.status_code == 200
                best[way] = (min(times), r)
            same = best["result_json"][1].json() == best["baseline"][1].json()
            assert same, f"{name}: the typed body differs from the stored one"
            kb = len(best["baseline"][1].content) / 1e3
            base = best["baseline"][0]
            view = "full" if full else "default"
            print(f"{name:<24}{view:<9}{kb:>8.0f}{base * 1e3:>13.1f}{best['result_json'][0] * 1e3:>13.1f}"
                  f"{best['result_json'][0] / base:>7.2f}{best['response_model'][0] * 1e3:>16.1f}"
                  f"{best['response_model'][0] / base:>7.2f}")
            figures[f"{name}.{view}"] = {
                "body_kb": round(kb, 1), "baseline_jsonresponse_ms": round(base * 1e3, 2),
                "result_json_ms": round(best["result_json"][0] * 1e3, 2),
                "result_json_ratio": round(best["result_json"][0] / base, 3),
                "fastapi_response_model_ms": round(best["response_model"][0] * 1e3, 2),
                "fastapi_response_model_ratio": round(best["response_model"][0] / base, 3)}
    write_results("result_body", figures)


if __name__ == "__main__":
    main()
