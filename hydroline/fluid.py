"""Hydraulic fluid properties (SI units throughout)."""
from __future__ import annotations

from dataclasses import dataclass

__all__ = ["Fluid", "effective_bulk_modulus", "MINERAL_OIL"]


def _positive(name: str, value: float, unit: str) -> float:
    value = float(value)
    if not value > 0 or value != value or value == float("inf"):
        raise ValueError(f"{name} must be a positive finite number in [{unit}], got {value!r}")
    return value


@dataclass(frozen=True)
class Fluid:
    """A hydraulic fluid.

    Parameters
    ----------
    density : float              Mass density rho, [kg/m^3]
    kinematic_viscosity : float  Kinematic viscosity nu, [m^2/s]
    bulk_modulus : float         Isentropic bulk modulus of the pure (air-free) oil, [Pa]
    """

    density: float
    kinematic_viscosity: float
    bulk_modulus: float

    def __post_init__(self):
        object.__setattr__(self, "density", _positive("density", self.density, "kg/m^3"))
        object.__setattr__(self, "kinematic_viscosity",
                           _positive("kinematic_viscosity", self.kinematic_viscosity, "m^2/s"))
        object.__setattr__(self, "bulk_modulus", _positive("bulk_modulus", self.bulk_modulus, "Pa"))

    @property
    def dynamic_viscosity(self) -> float:
        """Dynamic viscosity mu = rho*nu, [Pa s]."""
        return self.density * self.kinematic_viscosity


#: ISO VG 32 mineral hydraulic oil near 40 degC: rho = 870 kg/m^3, nu = 32 cSt
#: (ISO 3448 grade mid-point), pure-oil bulk modulus 1.5 GPa (McCloy & Martin,
#: "Control of Fluid Power", typical mineral oil value).
MINERAL_OIL = Fluid(density=870.0, kinematic_viscosity=3.2e-5, bulk_modulus=1.5e9)


def effective_bulk_modulus(oil_bulk_modulus: float, wall_bulk_modulus: float | None = None,
                           air_fraction: float = 0.0, pressure: float | None = None,
                           polytropic_exponent: float = 1.0) -> float:
    """Effective bulk modulus of oil in a compliant hose, compliances in series.

    ``1/beta_e = 1/beta_oil + 1/beta_wall + (V_air/V_total)/beta_air`` (MODEL.md section 2),
    with the air's bulk modulus ``beta_air = m * p`` (polytropic gas at absolute pressure p).

    Parameters
    ----------
    oil_bulk_modulus : float      Bulk modulus of the pure oil, [Pa]
    wall_bulk_modulus : float     Effective bulk modulus of the hose wall, ``V dp/dV`` of the
                                  hose volume alone (for a thin elastic tube ``E t / d``), [Pa];
                                  None for a rigid wall
    air_fraction : float          Volume fraction of entrained (undissolved) air at ``pressure``, [-]
    pressure : float              Absolute pressure at which the air fraction is given, [Pa];
                                  required when air_fraction > 0
    polytropic_exponent : float   Exponent m of the air, 1 (isothermal) ... 1.4 (adiabatic), [-]

    Returns
    -------
    float  Effective bulk modulus, [Pa]
    """
    compliance = 1.0 / _positive("oil_bulk_modulus", oil_bulk_modulus, "Pa")
    if wall_bulk_modulus is not None:
        compliance += 1.0 / _positive("wall_bulk_modulus", wall_bulk_modulus, "Pa")
    if air_fraction:
        if not 0 < air_fraction < 1:
            raise ValueError(f"air_fraction must lie in [0, 1) [-], got {air_fraction!r}")
        if pressure is None:
            raise ValueError("pressure [Pa] (absolute) is required when air_fraction > 0")
        beta_air = _positive("polytropic_exponent", polytropic_exponent, "-") * _positive(
            "pressure", pressure, "Pa")
        compliance += air_fraction / beta_air
    return 1.0 / compliance
