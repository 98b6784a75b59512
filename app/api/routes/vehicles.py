"""/v1/vehicles: the named vehicles a reentry job may fly (``params.vehicle.preset``), with their
data, planet and atmosphere in API units (:mod:`app.kinds.reentry.vehicle`)."""
from __future__ import annotations

from fastapi import APIRouter, HTTPException

from app.kinds.reentry.vehicle import VehicleOut, vehicle_out
from app.api.schemas import ErrorBody
from solvers.models.vehicles import VEHICLES

router = APIRouter(prefix="/v1/vehicles", tags=["vehicles"])


@router.get("", response_model=list[VehicleOut])
def list_vehicles():
    return [vehicle_out(name) for name in VEHICLES]


@router.get("/{name}", response_model=VehicleOut,
            responses={404: {"model": ErrorBody, "description": "Unknown vehicle"}})
def get_vehicle(name: str):
    if name not in VEHICLES:
        raise HTTPException(status_code=404, detail=f"vehicle {name} not found; known: {sorted(VEHICLES)}")
    return vehicle_out(name)
