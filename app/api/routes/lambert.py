"""POST /v1/lambert: synchronous batched Lambert solves (no queue).

Problems are grouped by branch (revolutions, direction, path) so each group is
one call of the vectorized solver; answers come back in request order.
"""
from __future__ import annotations

import math
from typing import Annotated, Callable

import numpy as np
from fastapi import APIRouter, Body, Depends, Request
from fastapi.exceptions import RequestValidationError
from fastapi.routing import APIRoute
from pydantic import Field, field_validator

from app.api.access import bearer_scheme, principal_before_body
from app.kinds.base import StrictModel
from app.api.limits import count_lambert_problems
from app.api.schemas import ValidationErrorBody
from app.runtime.settings import get_settings
from solvers.astro.earth import AE_EARTH
from solvers.astro.lambert import arc_min_radius, lambert



def _finite_json(value):
    """Non-finite floats as strings: a 422 echoing a NaN input must still be valid JSON."""
    if isinstance(value, float) and not math.isfinite(value):
        return str(value)
    if isinstance(value, dict):
        return {k: _finite_json(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite_json(v) for v in value]
    return value


class _FiniteErrorsRoute(APIRoute):
    """Python's JSON parser accepts NaN; pydantic rejects it but echoes it in the error,
    which the default handler cannot serialize (a 500 instead of the 422)."""

    def get_route_handler(self) -> Callable:
        handler = super().get_route_handler()

        async def route_handler(request: Request):
            # The key, then the cap, are checked before the array is parsed (up to 25 MB at the
            # default cap): the cap on the raw body (app.api.limits), which is kept on the request,
            # so FastAPI parses the same bytes without reading again.
            await principal_before_body(request)
            cap = _settings(request).lambert_max_problems
            if count_lambert_problems(await request.body()) > cap:
                raise RequestValidationError([_too_many(cap, "more than")])
            try:
                return await handler(request)
            except RequestValidationError as exc:
                raise RequestValidationError([_finite_json(dict(e)) for e in exc.errors()]) from None

        return route_handler


router = APIRouter(prefix="/v1", tags=["lambert"], route_class=_FiniteErrorsRoute)

# Body cap of this route: room for the problem cap at up to this many bytes per problem (a problem
# with full-precision floats and every optional field is about 230 bytes).
BYTES_PER_PROBLEM = 256


def max_body_bytes(settings) -> int:
    return max(settings.max_body_bytes, settings.lambert_max_problems * BYTES_PER_PROBLEM)


def _settings(request: Request):
    return getattr(request.app.state, "settings", None) or get_settings()


def _too_many(cap: int, got) -> dict:
    return {"loc": ("body", "problems"), "type": "too_long", "input": None,
            "msg": f"at most {cap} problems per request (TRAJLAB_LAMBERT_MAX_PROBLEMS), got {got}"}

MU_EARTH_M3_S2 = 398600.4418e9
# Bounds that keep every case physical and the arithmetic finite (1e300 m used to come back as an
# unconverged answer): a light-day of position, ~300 years of flight, mu from a small asteroid to ~10^4 Suns.
MAX_POSITION_M = 2.6e13
MAX_TOF_S = 1e10
MU_RANGE_M3_S2 = (1e5, 1e24)

Vector3 = Annotated[list[float], Field(min_length=3, max_length=3)]


class LambertProblem(StrictModel):
    r1_m: Vector3 = Field(description="Departure position (inertial), m", examples=[[5000e3, 10000e3, 2100e3]])
    r2_m: Vector3 = Field(description="Arrival position (inertial), m", examples=[[-14600e3, 2500e3, 7000e3]])
    tof_s: float = Field(gt=0, le=MAX_TOF_S, description="Time of flight, s", examples=[3600.0])
    revolutions: int = Field(0, ge=0, le=50, description="Full revolutions before arrival", examples=[0])
    prograde: bool = Field(True, description="Transfer angular momentum with positive z (Izzo/pykep convention)",
                           examples=[True])
    low_path: bool = Field(True, description="For revolutions > 0: which of the two solutions "
                           "(true: the larger Izzo x, as poliastro's lowpath)", examples=[True])

    @field_validator("r1_m", "r2_m")
    @classmethod
    def _nonzero(cls, v):
        norm = math.hypot(*v)
        if norm == 0.0:
            raise ValueError("position must not be the zero vector")
        if norm > MAX_POSITION_M:
            raise ValueError(f"position magnitude must be at most {MAX_POSITION_M:g} m (about a light-day)")
        return v


class LambertRequest(StrictModel):
    mu_m3_s2: float = Field(MU_EARTH_M3_S2, ge=MU_RANGE_M3_S2[0], le=MU_RANGE_M3_S2[1],
                            description="Gravitational parameter, m^3/s^2",
                            examples=[MU_EARTH_M3_S2])
    problems: list[LambertProblem] = Field(min_length=1, description="The cases to solve (up to the "
                                           "configured cap, TRAJLAB_LAMBERT_MAX_PROBLEMS)")
    body_radius_m: float | None = Field(AE_EARTH, gt=0, le=MAX_POSITION_M,
                                        description="Radius of the central body: a transfer whose periapsis_m is "
                                        "below it passes through the planet (through_planet). Default: the "
                                        "Earth's equatorial radius (WGS-84); null: no check",
                                        examples=[AE_EARTH])


class LambertAnswer(StrictModel):
    v1_mps: list[float] | None = Field(description="Departure velocity, m/s; null if no solution")
    v2_mps: list[float] | None = Field(description="Arrival velocity, m/s; null if no solution")
    converged: bool = Field(description="False where no solution exists (e.g. a multi-revolution transfer "
                            "shorter than its minimum time, or r1 and r2 collinear)")
    iterations: int = Field(description="Householder iterations")
    periapsis_m: float | None = Field(description="Smallest radius along the arc actually flown: the transfer "
                                      "orbit's periapsis radius if the arc passes through periapsis between r1 "
                                      "and r2, else min(|r1|, |r2|); null if no solution")
    through_planet: bool | None = Field(description="periapsis_m is below body_radius_m: the arc passes through "
                                        "the central body (the solution is still returned and converged); null "
                                        "if no solution or body_radius_m is null")
    revolutions: int
    prograde: bool
    low_path: bool


class LambertResponse(StrictModel):
    solutions: list[LambertAnswer]


@router.post("/lambert", response_model=LambertResponse,
             # the key is checked before the body (route class above); this declares the scheme in /docs
             dependencies=[Depends(bearer_scheme)],
             responses={422: {"model": ValidationErrorBody, "description": "A bad vector (length != 3, NaN, zero, absurd magnitude), tof_s "
                                             "<= 0 or absurd, mu out of range, or more problems than the cap"}})
def solve_lambert(request: Request, body: Annotated[LambertRequest, Body(openapi_examples={
    "curtis-5.2": {"summary": "Curtis example 5.2 (in m)", "value": {
        "mu_m3_s2": 398600e9,
        "problems": [{"r1_m": [5000e3, 10000e3, 2100e3], "r2_m": [-14600e3, 2500e3, 7000e3], "tof_s": 3600}]}},
})]) -> LambertResponse:
    """Solve a batch of Lambert problems (Izzo 2015, one compiled loop: about 3 million solves/s).

    Branch conventions, as the peers: `low_path` as hapsira/lamberthub's `lowpath` (for
    revolutions > 0, true picks the solution with the larger Izzo x); `prograde` as pykep's
    `cw = not prograde` (the transfer's angular momentum has a positive z component). In a plane
    that contains the z axis the normal's z component is zero and `prograde` picks the way by the
    sign of that normal as computed from r1 x r2. Positions beyond 2.6e13 m, times of flight beyond
    1e10 s and mu outside [1e5, 1e24] m^3/s^2 are a 422. Each answer carries `periapsis_m`, the
    smallest radius along the arc flown, and `through_planet`, whether it is below `body_radius_m`
    (default the Earth's equatorial radius; null for no check)."""
    cap = _settings(request).lambert_max_problems
    if len(body.problems) > cap:  # the exact count (the raw-body count above is an early bound)
        raise RequestValidationError([_too_many(cap, len(body.problems))])
    n = len(body.problems)
    r1 = np.array([p.r1_m for p in body.problems], dtype=float)
    r2 = np.array([p.r2_m for p in body.problems], dtype=float)
    tof = np.array([p.tof_s for p in body.problems], dtype=float)
    keys = [(p.revolutions, p.prograde, p.low_path) for p in body.problems]
    v1 = np.full((n, 3), np.nan)
    v2 = np.full((n, 3), np.nan)
    conv = np.zeros(n, dtype=bool)
    iters = np.zeros(n, dtype=int)
    rmin = np.full(n, np.nan)
    for key in sorted(set(keys)):
        idx = np.array([k for k, kk in enumerate(keys) if kk == key])
        sol = lambert(body.mu_m3_s2, r1[idx], r2[idx], tof[idx],
                      revolutions=key[0], prograde=key[1], low_path=key[2])
        v1[idx], v2[idx], conv[idx], iters[idx] = sol.v1, sol.v2, sol.converged, sol.iterations
        rmin[idx] = arc_min_radius(body.mu_m3_s2, r1[idx], sol.v1, r2[idx], sol.v2, revolutions=key[0])
    ok = conv & np.isfinite(rmin)
    radius = body.body_radius_m
    return LambertResponse(solutions=[
        LambertAnswer(v1_mps=v1[k].tolist() if conv[k] else None, v2_mps=v2[k].tolist() if conv[k] else None,
                      converged=bool(conv[k]), iterations=int(iters[k]),
                      periapsis_m=float(rmin[k]) if ok[k] else None,
                      through_planet=bool(rmin[k] < radius) if ok[k] and radius is not None else None,
                      revolutions=keys[k][0], prograde=keys[k][1], low_path=keys[k][2])
        for k in range(n)
    ])
