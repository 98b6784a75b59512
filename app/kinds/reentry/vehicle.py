"""The API mirror of the vehicle, planet and atmosphere models (:mod:`solvers.models`).

A reentry job names a vehicle preset (``params.vehicle.preset``: ``shuttle``, ``msl``; listed by
``GET /v1/vehicles``) and may override any part of it inline: mass, area, aerodynamics (CL/CD
polynomials in alpha degrees, or tables against alpha and Mach), heating model (Betts' fit or
Sutton-Graves with a nose radius); ``params.planet`` and ``params.atmosphere`` replace the
preset's planet and atmosphere.  Tables are validated by the solver's own dataclasses (one rule
set: strictly increasing breakpoints, shapes, positive densities), so a malformed table is a 422
naming the rule.  Units: SI, angles in degrees.
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Literal

from pydantic import Field, model_validator

from app.kinds.base import StrictModel
from solvers.models import aerodynamics, atmosphere, planet, vehicles
from solvers.models.shuttle import Vehicle

if TYPE_CHECKING:  # the names are data (solvers.models.vehicles), which a type checker does not run
    VehicleName = str
    PlanetName = str
else:
    VehicleName = Literal[tuple(vehicles.VEHICLES)]
    PlanetName = Literal[tuple(vehicles.PLANETS)]
AtmosphereName = Literal["exponential", "us1976", "mars"]
_ATMOSPHERE_NAMES = {"exponential": "betts", "us1976": "us1976", "mars": "mars"}
_MAX_BREAKPOINTS = 200


class ReentryAeroTable(StrictModel):
    alpha_deg: list[float] = Field(min_length=4, max_length=_MAX_BREAKPOINTS, description="Angle-of-attack "
                                   "breakpoints, strictly increasing (at least 4)", examples=[[-20.0, -16.0, -12.0, -8.0]])
    mach: list[float] = Field(min_length=1, max_length=_MAX_BREAKPOINTS, description="Mach breakpoints, "
                              "strictly increasing: 1 (no Mach dependence) or at least 4", examples=[[1.0]])
    cl: list[list[float]] = Field(description="CL, one row per alpha breakpoint, one column per Mach "
                                  "breakpoint", examples=[[[0.40], [0.35], [0.29], [0.22]]])
    cd: list[list[float]] = Field(description="CD, same shape as cl", examples=[[[1.55], [1.58], [1.60], [1.62]]])

    @model_validator(mode="after")
    def _valid(self):
        self.to_solver()   # the solver's rules; a ValueError is a 422 naming the rule
        return self

    def to_solver(self) -> aerodynamics.AeroTable:
        return aerodynamics.AeroTable(alpha_deg=tuple(self.alpha_deg), mach=tuple(self.mach), cl=self.cl, cd=self.cd)

    @classmethod
    def from_solver(cls, t: aerodynamics.AeroTable) -> ReentryAeroTable:
        return cls(alpha_deg=list(t.alpha_deg), mach=list(t.mach), cl=[list(r) for r in t.cl],
                   cd=[list(r) for r in t.cd])


class ReentryHeating(StrictModel):
    model: Literal["betts", "sutton_graves"] = Field("betts", description="Betts' shuttle fit (alpha "
                                                     "dependent), or Sutton-Graves q = k sqrt(rho/r_n) v^3",
                                                     examples=["sutton_graves"])
    nose_radius_m: float | None = Field(None, gt=0, description="Nose radius r_n (Sutton-Graves)",
                                        examples=[1.125])
    k: float | None = Field(None, gt=0, description="Sutton-Graves constant in SI (kg^0.5/m); null: the "
                            "planet's (Earth 1.7415e-4, Mars 1.9027e-4)", examples=[None])

    @model_validator(mode="after")
    def _radius(self):
        if self.model == "sutton_graves" and self.nose_radius_m is None:
            raise ValueError("sutton_graves needs nose_radius_m")
        return self


class ReentryPlanet(StrictModel):
    preset: PlanetName = Field("earth", description="Base planet: earth (Betts' constants) or mars (NASA "
                               "GSFC fact sheet); the fields below override it", examples=["mars"])
    mu_m3_s2: float | None = Field(None, gt=0, description="Gravitational parameter", examples=[4.28283e13])
    radius_m: float | None = Field(None, gt=0, description="Reference radius (altitude zero)",
                                   examples=[3396200.0])
    omega_rad_s: float | None = Field(None, ge=0, description="Rotation rate (used with rotating_earth)",
                                      examples=[7.088218e-5])
    j2: float | None = Field(None, ge=0, description="J2 (data only: the reentry dynamics use central "
                             "gravity)", examples=[0.00196045])
    sutton_graves_k: float | None = Field(None, gt=0, description="Sutton-Graves constant of the "
                                          "atmosphere's gas, SI", examples=[1.9027e-4])

    def to_solver(self) -> planet.Planet:
        import dataclasses
        over = {k: v for k, v in self.model_dump(exclude={"preset"}).items() if v is not None}
        return dataclasses.replace(vehicles.PLANETS[self.preset], **over)

    @classmethod
    def from_solver(cls, p: planet.Planet) -> ReentryPlanet:
        return cls(preset=p.name, mu_m3_s2=p.mu_m3_s2, radius_m=p.radius_m, omega_rad_s=p.omega_rad_s,
                   j2=p.j2, sutton_graves_k=p.sutton_graves_k)


class ReentryAtmosphereModel(StrictModel):
    kind: Literal["exponential", "us1976", "table"] = Field(description="exponential (rho0, scale "
                                                            "height), U.S. Standard 1976, or a table of "
                                                            "density against altitude (log-density spline)",
                                                            examples=["table"])
    rho0_kg_m3: float | None = Field(None, gt=0, description="exponential: density at altitude 0",
                                     examples=[0.0158])
    scale_height_m: float | None = Field(None, gt=0, description="exponential: scale height",
                                         examples=[11100.0])
    altitudes_m: list[float] | None = Field(None, min_length=4, max_length=_MAX_BREAKPOINTS,
                                            description="table: altitudes, strictly increasing",
                                            examples=[[0.0, 40000.0, 80000.0, 120000.0]])
    densities_kg_m3: list[float] | None = Field(None, min_length=4, max_length=_MAX_BREAKPOINTS,
                                                description="table: densities (> 0), one per altitude",
                                                examples=[[0.0158, 4.1e-4, 1.1e-5, 3.0e-7]])
    sound_speeds_mps: list[float] | None = Field(None, max_length=_MAX_BREAKPOINTS, description="table: "
                                                 "speed of sound per altitude (Mach of aero tables); "
                                                 "null: sound_speed_mps", examples=[None])
    sound_speed_mps: float = Field(340.294, gt=0, description="Constant speed of sound where the model "
                                   "has no temperature (exponential; table without sound_speeds_mps)",
                                   examples=[240.0])

    @model_validator(mode="after")
    def _valid(self):
        need = {"exponential": ("rho0_kg_m3", "scale_height_m"), "table": ("altitudes_m", "densities_kg_m3")}
        missing = [n for n in need.get(self.kind, ()) if getattr(self, n) is None]
        if missing:
            raise ValueError(f"atmosphere kind {self.kind} needs {', '.join(missing)}")
        self.to_solver()   # the solver's rules (monotone altitudes, lengths, positive densities)
        return self

    def to_solver(self) -> atmosphere.Atmosphere:
        d = {k: v for k, v in self.model_dump().items() if v is not None}
        return atmosphere.Atmosphere(**d)

    @classmethod
    def from_solver(cls, a: atmosphere.Atmosphere) -> ReentryAtmosphereModel:
        if a.kind == "exponential":
            return cls(kind="exponential", rho0_kg_m3=a.rho0_kg_m3, scale_height_m=a.scale_height_m,
                       sound_speed_mps=a.sound_speed_mps)
        if a.kind == "us1976":
            return cls(kind="us1976")
        return cls(kind="table", altitudes_m=list(a.altitudes_m), densities_kg_m3=list(a.densities_kg_m3),
                   sound_speeds_mps=list(a.sound_speeds_mps) or None, sound_speed_mps=a.sound_speed_mps)


def has_aero_table(name: str) -> bool:
    """Whether the named vehicle's aerodynamics are a table (not polynomials)."""
    return vehicles.VEHICLES[name].vehicle.aero_table is not None


def named_atmosphere(name: str) -> atmosphere.Atmosphere:
    """``exponential`` (Betts' Earth), ``us1976`` or ``mars`` (the Glenn Mars table)."""
    return vehicles.ATMOSPHERES[_ATMOSPHERE_NAMES[name]]


class VehicleData(StrictModel):
    """A vehicle preset's data in API units (``GET /v1/vehicles``): exactly the fields ``params.vehicle``
    takes (``ReentryVehicle``), so it can be pasted there and edited (a test holds the round trip).
    Betts' heating fit has no numbers here: ``heating.model: betts`` names it (Betts' shuttle
    coefficients, ``solvers.models.shuttle``)."""

    preset: VehicleName = Field(description="The vehicle's own name: as params.vehicle.preset, the base the "
                                "other fields override")
    mass_kg: float = Field(description="Mass (kg)")
    area_m2: float = Field(description="Reference area (m^2)")
    cl_coeffs: list[float] | None = Field(description="CL polynomial in alpha degrees (null: table)")
    cd_coeffs: list[float] | None = Field(description="CD polynomial in alpha degrees (null: table)")
    aero_table: ReentryAeroTable | None = Field(description="CL and CD against alpha (deg) and Mach (null: "
                                                "polynomials)")
    heating: ReentryHeating = Field(description="Heating model")


class VehicleOut(StrictModel):
    name: str
    description: str
    vehicle: VehicleData
    planet: ReentryPlanet
    atmosphere: ReentryAtmosphereModel


def vehicle_out(name: str) -> dict:
    """A vehicle preset as ``GET /v1/vehicles/{name}`` shows it (``KeyError`` if unknown)."""
    p = vehicles.vehicle_preset(name)
    v: Vehicle = p.vehicle
    table = v.aero_table
    heating = (ReentryHeating(model="sutton_graves", nose_radius_m=v.heating.nose_radius_m, k=v.heating.k)
               if v.heating is not None else ReentryHeating(model="betts"))
    data = VehicleData(preset=name, mass_kg=v.mass_kg, area_m2=v.area_m2,
                       cl_coeffs=None if table else list(v.cl_coeffs), cd_coeffs=None if table else list(v.cd_coeffs),
                       aero_table=ReentryAeroTable.from_solver(table) if table else None, heating=heating)
    return VehicleOut(name=p.name, description=p.description, vehicle=data,
                      planet=ReentryPlanet.from_solver(v.planet),
                      atmosphere=ReentryAtmosphereModel.from_solver(v.atmosphere)).model_dump()
