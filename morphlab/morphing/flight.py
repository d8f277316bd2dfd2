"""Flight conditions of the wing section: the freestream, its Reynolds number on the 550 mm chord,
and the two configurations of the paper (high speed with the undeformed nose, thermalling with
the drooped nose) for a high-performance 18 m class sailplane.

Units: flight quantities in SI (speed m/s, density kg/m³, dynamic viscosity Pa·s, wing loading
kg/m², altitude m, dynamic pressure Pa); the chord in mm and pressures on the structure in MPa
(N/mm²), the model's units. Angles in degrees.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..errors import ModelError
from .cst import CHORD_MM

__all__ = ["G0", "isa", "FlightCondition", "sailplane_condition", "SAILPLANE",
           "HIGH_SPEED", "THERMALLING", "CONDITIONS"]

#: Standard gravity [m/s²].
G0 = 9.80665


def isa(altitude: float) -> dict:
    """International Standard Atmosphere in the troposphere (ISO 2533 / ICAO Doc 7488).

    Parameters
    ----------
    altitude : float
        Geopotential altitude [m], 0 ... 11000.

    Returns
    -------
    dict
        ``temperature`` [K], ``pressure`` [Pa], ``density`` [kg/m³], ``viscosity`` (dynamic,
        Sutherland's law) [Pa·s], ``speed_of_sound`` [m/s].

    Notes
    -----
    ``T = 288.15 - 0.0065 h``, ``p = 101325 (T / 288.15)**5.25588``, ``rho = p / (287.05287 T)``,
    ``mu = 1.458e-6 T**1.5 / (T + 110.4)``, ``a = sqrt(1.4 * 287.05287 * T)``.
    """
    h = float(altitude)
    if not 0.0 <= h <= 11000.0:
        raise ModelError(f"altitude must lie in [0, 11000] m (troposphere), got {altitude}")
    t = 288.15 - 0.0065 * h
    p = 101325.0 * (t / 288.15) ** 5.25588
    r_air = 287.05287
    return {"temperature": t, "pressure": p, "density": p / (r_air * t),
            "viscosity": 1.458e-6 * t**1.5 / (t + 110.4),
            "speed_of_sound": float(np.sqrt(1.4 * r_air * t))}


@dataclass(frozen=True)
class FlightCondition:
    """The freestream of a wing-section analysis.

    Parameters
    ----------
    speed : float
        True airspeed [m/s].
    density : float, optional
        Air density [kg/m³]; default sea level (ISA), 1.225.
    viscosity : float, optional
        Dynamic viscosity [Pa·s]; default sea level (ISA), 1.789e-5.
    alpha : float, optional
        Angle of attack [deg] of the freestream against the x axis of the wing section (the
        undeformed chord line; the fixed rear part does not move).
    cl : float, optional
        Target lift coefficient on :attr:`chord`; the analysis finds the angle of attack.
        Give exactly one of ``alpha`` and ``cl``.
    chord : float, optional
        Reference chord [mm]; default 550 mm.
    n_crit : float, optional
        Critical amplification factor of the e^N transition model; default 9 (the standard
        e^9 method; the XFOIL manual suggests 12-14 for sailplanes in free flight, so 9 puts
        transition somewhat early, on the safe side for the drag).
    name : str, optional
        Label.
    """

    speed: float
    density: float = 1.225
    viscosity: float = 1.789e-5
    alpha: float | None = None
    cl: float | None = None
    chord: float = CHORD_MM
    n_crit: float = 9.0
    name: str = ""

    def __post_init__(self) -> None:
        for key in ("speed", "density", "viscosity", "chord"):
            v = getattr(self, key)
            if not (np.isreal(v) and np.isfinite(v) and v > 0.0):
                raise ModelError(f"FlightCondition.{key} must be a positive finite number, "
                                 f"got {v!r}")
        if (self.alpha is None) == (self.cl is None):
            raise ModelError("FlightCondition needs exactly one of alpha (deg) and cl, got "
                             f"alpha={self.alpha!r}, cl={self.cl!r}")
        if self.alpha is not None and not (np.isfinite(self.alpha) and abs(self.alpha) < 25.0):
            raise ModelError(f"alpha must be a finite angle in (-25, 25) deg, got {self.alpha!r}")
        if self.cl is not None and not (np.isfinite(self.cl) and abs(self.cl) < 2.5):
            raise ModelError(f"cl must be finite and in (-2.5, 2.5), got {self.cl!r}")
        if not 0.0 < self.n_crit <= 20.0:
            raise ModelError(f"n_crit must lie in (0, 20], got {self.n_crit!r}")

    @property
    def dynamic_pressure(self) -> float:
        """``rho V**2 / 2`` [Pa]."""
        return 0.5 * self.density * self.speed**2

    @property
    def q_mpa(self) -> float:
        """Dynamic pressure in the model's units [MPa = N/mm²]."""
        return 1e-6 * self.dynamic_pressure

    @property
    def reynolds(self) -> float:
        """Reynolds number on the chord, ``rho V c / mu``."""
        return self.density * self.speed * (1e-3 * self.chord) / self.viscosity

    def at(self, *, alpha: float | None = None, cl: float | None = None) -> FlightCondition:
        """Copy at another angle of attack or target lift coefficient (give one)."""
        return replace(self, alpha=alpha, cl=cl)


def sailplane_condition(speed_kmh: float, wing_loading: float, altitude: float, *,
                        bank_deg: float = 0.0, name: str = "", n_crit: float = 9.0,
                        chord: float = CHORD_MM) -> FlightCondition:
    """Flight condition of a sailplane in steady level or circling flight.

    Parameters
    ----------
    speed_kmh : float
        True airspeed [km/h].
    wing_loading : float
        Mass per wing area [kg/m²].
    altitude : float
        ISA altitude [m] (:func:`isa`).
    bank_deg : float, optional
        Bank angle of a steady turn [deg]; the load factor is ``1 / cos(bank)``.
    name, n_crit, chord
        As in :class:`FlightCondition`.

    Returns
    -------
    FlightCondition
        With the lift coefficient the wing needs: ``cl = n (m/S) g / q``. The section is
        taken to carry the wing's mean lift coefficient (the spanwise distribution of an
        elliptically loaded wing; locally it differs by some per cent).
    """
    if not 0.0 <= bank_deg < 75.0:
        raise ModelError(f"bank_deg must lie in [0, 75), got {bank_deg}")
    if not wing_loading > 0.0:
        raise ModelError(f"wing_loading must be positive, got {wing_loading}")
    atm = isa(altitude)
    v = speed_kmh / 3.6
    q = 0.5 * atm["density"] * v * v
    n = 1.0 / np.cos(np.radians(bank_deg))
    return FlightCondition(speed=v, density=atm["density"], viscosity=atm["viscosity"],
                           cl=float(n * wing_loading * G0 / q), chord=chord, n_crit=n_crit,
                           name=name)


#: The representative sailplane: Schleicher ASG 29 with 18 m span, wing area 10.5 m²,
#: maximum take-off mass 600 kg (manufacturer's published type data), so the wing loading
#: ranges from about 38 kg/m² (no water ballast, ~400 kg) to 57 kg/m² (600 kg).
SAILPLANE = {"type": "Schleicher ASG 29 (18 m class)", "span_m": 18.0, "wing_area_m2": 10.5,
             "mass_max_kg": 600.0, "mass_light_kg": 400.0}

#: High-speed configuration (undeformed nose): inter-thermal cruise at 180 km/h, fully
#: ballasted (600 kg, 57.1 kg/m²), 1500 m ISA. CL = 0.42, q = 1.32 kPa, Re = 1.67e6.
HIGH_SPEED = sailplane_condition(180.0, SAILPLANE["mass_max_kg"] / SAILPLANE["wing_area_m2"],
                                 1500.0, name="high speed")

#: Low-speed configuration (drooped nose): circling in a thermal at 95 km/h and 30 deg bank
#: (load factor 1.155) without ballast (400 kg, 38.1 kg/m²), 1500 m ISA. CL = 1.17,
#: q = 0.368 kPa, Re = 0.88e6.
THERMALLING = sailplane_condition(95.0, SAILPLANE["mass_light_kg"] / SAILPLANE["wing_area_m2"],
                                  1500.0, bank_deg=30.0, name="thermalling")

#: The two configurations by name.
CONDITIONS = {"high_speed": HIGH_SPEED, "thermalling": THERMALLING}
