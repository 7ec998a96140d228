"""Optional submodels of the engine model: the physical extensions a fit to measured data can select.

The thesis model (chapter 3) is the base.  Each submodel replaces or extends one piece of it and is
``None`` (off) by default; with every submodel off the compiled model runs the base code path, bit
for bit.  The choice of submodels and their values is part of :class:`~marine_fdi_env.engine.params.EngineParams`
(field ``submodels``), so the dynamic simulator, the steady-state solvers, the environment and the
diagnoser all run the same extended engine (one model, optional submodels, as PyBaMM's
``BatteryModelOptions``).

=====================  =================================================================================
submodel               what it changes (where)
=====================  =================================================================================
``speed_law``          controllable-pitch propeller: combinator line ``n/n_nom = s0 + (s1 - s0) P/P_nom``
                       instead of the propeller law ``P = c n^3`` (eq. 3.11; Σ2 speed loop)
``friction``           extra friction mean effective pressure ``a + d (n/n_nom)^2`` (eq. 3.10; Σ2)
``turbocharger_map``   ``η_TC = s η_TC,3.33(p1_nom) (1 - w (x4/p1_nom - 1)^2)`` instead of eq. 3.33 (Σ3, Σ4)
``intercooler``        cooler outlet ``T_c`` following the cooler inlet with an effectiveness (eq. 3.37; Σ4)
``cylinder_heat_loss`` polytropic compression exponent and a change of the expansion exponent (table B.1)
``waste_gate``         exhaust bypassing the turbine through an orifice in parallel with it, rejoining
                       after the turbine outlet thermocouple (Σ3)
``bypass_valve``       charge air from the charge-air receiver to the turbine inlet through an orifice (Σ3, Σ4)
``turbine_flow_law``   swallowing capacity: effective-area scale and the pressure-ratio exponent of the
                       ellipse law (eq. 3.16; Σ3)
``turbine_efficiency_bsr``  turbine efficiency falling away from an optimum blade-speed ratio (eq. 3.26)
``exhaust_heat_loss``  heat lost by the exhaust between the cylinders and the turbine, growing as the flow
                       falls (Σ3)
=====================  =================================================================================

Valve openings (waste gate, bypass) are :class:`Schedule` s: piecewise linear in the fuel setting
``u = x1 / x1_nom`` (the fuel-pump state, so there is no algebraic loop in the dynamic model and it
works under any load law), constant outside the knots.  A fit that finds one opening per measured
point stores them as a schedule with one knot per point.

Ambient conditions are not a submodel: they are parameters (``T_amb_K``, ``p_amb_Pa``, ``p_ex_Pa``).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

__all__ = [
    "Schedule",
    "CombinatorSpeed",
    "ExtraFriction",
    "TurbochargerMap",
    "Intercooler",
    "CylinderHeatLoss",
    "WasteGate",
    "BypassValve",
    "TurbineFlowLaw",
    "TurbineEfficiencyBSR",
    "ExhaustHeatLoss",
    "EngineSubmodels",
    "NO_SUBMODELS",
    "SUBMODEL_TYPES",
    "BYPASS_JUNCTIONS",
]

BYPASS_JUNCTIONS = ("receiver", "turbine")


def _finite(owner: str, name: str, value: Any) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{owner}.{name} must be a number, got {value!r}") from None
    if not math.isfinite(v):
        raise ValueError(f"{owner}.{name} must be finite, got {value!r}")
    return v


def _in_range(owner: str, name: str, value: Any, lo: float, hi: float) -> float:
    v = _finite(owner, name, value)
    if not lo <= v <= hi:
        raise ValueError(f"{owner}.{name} must lie in [{lo:g}, {hi:g}], got {v!r}")
    return v


@dataclass(frozen=True)
class Schedule:
    """A valve opening as a piecewise-linear function of the fuel setting ``u = x1/x1_nom``.

    u : knots, strictly increasing (fuel settings).  value : opening at each knot (same length,
    >= 0).  Outside the knots the opening stays at the first/last value.  One knot is a constant.
    """

    u: tuple[float, ...]
    value: tuple[float, ...]

    def __post_init__(self) -> None:
        u = tuple(_finite("schedule", "u", x) for x in self.u)
        v = tuple(_finite("schedule", "value", x) for x in self.value)
        if len(u) == 0 or len(u) != len(v):
            raise ValueError(
                f"schedule needs as many openings as knots (at least one), got {len(u)} knots and {len(v)} openings"
            )
        if any(b <= a for a, b in zip(u, u[1:])):
            raise ValueError(f"schedule knots u must be strictly increasing, got {list(u)}")
        if any(x < 0 for x in v):
            raise ValueError(f"schedule openings must be >= 0, got {list(v)}")
        object.__setattr__(self, "u", u)
        object.__setattr__(self, "value", v)

    @classmethod
    def constant(cls, value: float) -> "Schedule":
        return cls((1.0,), (float(value),))

    def at(self, u) -> np.ndarray:
        """Opening at fuel setting(s) u (constant extrapolation)."""
        return np.interp(np.asarray(u, float), self.u, self.value)

    @property
    def max(self) -> float:
        return max(self.value)

    def as_dict(self) -> dict[str, list[float]]:
        return {"u": list(self.u), "value": list(self.value)}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any], owner: str = "schedule") -> "Schedule":
        if isinstance(d, (int, float)):
            return cls.constant(float(d))
        if not isinstance(d, Mapping) or "u" not in d or "value" not in d:
            raise ValueError(f'{owner} must be a number or an object {{"u": [...], "value": [...]}}, got {d!r}')
        return cls(tuple(d["u"]), tuple(d["value"]))


@dataclass(frozen=True)
class CombinatorSpeed:
    """Controllable-pitch propeller on a combinator line ``n/n_nom = s0 + (s1 - s0) P/P_nom``.

    speed_zero_load_rel (s0), speed_full_load_rel (s1): engine speed at zero and at nominal load,
    relative to n_nom.  Replaces eq. 3.11 in the speed loop of Σ2.
    """

    speed_zero_load_rel: float = 0.8
    speed_full_load_rel: float = 1.0

    def __post_init__(self) -> None:
        _in_range("speed_law", "speed_zero_load_rel", self.speed_zero_load_rel, 0.1, 1.5)
        _in_range("speed_law", "speed_full_load_rel", self.speed_full_load_rel, 0.5, 1.5)


@dataclass(frozen=True)
class ExtraFriction:
    """Extra friction mean effective pressure ``Δfmep = a + d (n/n_nom)^2`` [Pa] added to eq. 3.10
    (Chen-Flynn-like: a constant part, and a part growing with the square of the piston speed)."""

    fmep_offset_Pa: float = 0.0
    fmep_speed2_Pa: float = 0.0

    def __post_init__(self) -> None:
        _in_range("friction", "fmep_offset_Pa", self.fmep_offset_Pa, -5e5, 5e5)
        _in_range("friction", "fmep_speed2_Pa", self.fmep_speed2_Pa, -5e5, 5e5)


@dataclass(frozen=True)
class TurbochargerMap:
    """Turbocharger efficiency ``η_TC = s η_TC,3.33(p1_nom) (1 - w (x4/p1_nom - 1)^2)`` instead of
    eq. 3.33; the turbine efficiency keeps the calibration's ratio ``η_turbo = η_TC/(η_c η_com)``."""

    eta_scale: float = 1.0
    curvature: float = 0.3

    def __post_init__(self) -> None:
        _in_range("turbocharger_map", "eta_scale", self.eta_scale, 0.3, 1.6)
        _in_range("turbocharger_map", "curvature", self.curvature, 0.0, 5.0)


@dataclass(frozen=True)
class Intercooler:
    """Charge-air cooler outlet following its inlet (eq. 3.37 takes T_c constant):
    ``T_c = T_c,nom + dT_outlet + (1 - ε)(T_co,is(x4) - T_co,is(p1_nom))`` with the isentropic
    compressor outlet ``T_co,is`` at η_c (no algebraic loop through the turbine temperatures).

    effectiveness (ε) : 1 = the constant T_c of the base model.  dT_outlet_K : outlet temperature at
    the nominal charge pressure minus the parameter set's T_c (the cooling-water temperature of a test).
    """

    effectiveness: float = 1.0
    dT_outlet_K: float = 0.0

    def __post_init__(self) -> None:
        _in_range("intercooler", "effectiveness", self.effectiveness, 0.0, 1.0)
        _in_range("intercooler", "dT_outlet_K", self.dT_outlet_K, -60.0, 60.0)


@dataclass(frozen=True)
class CylinderHeatLoss:
    """Heat transfer to the cylinder walls: polytropic compression exponent ``n_comp`` (eq. B.1-B.9
    use κa) and a change ``dn_exp`` of the expansion exponent n_exp (table B.1, stage 5-6)."""

    n_comp: float = 1.4
    dn_exp: float = 0.0

    def __post_init__(self) -> None:
        _in_range("cylinder_heat_loss", "n_comp", self.n_comp, 1.1, 1.6)
        _in_range("cylinder_heat_loss", "dn_exp", self.dn_exp, -0.3, 0.3)


@dataclass(frozen=True)
class WasteGate:
    """Exhaust gas bypassing the turbine through a waste-gate orifice (Σ3).

    The orifice sits in parallel with the turbine between the exhaust receiver (x3) and the turbine
    outlet (p_ex) and follows the same compressible flow law as the turbine (eq. 3.16): with the
    opening ``a = A_wg / A_eff`` the receiver passes the exhaust through ``A_eff (1 + a)`` and the
    turbine gets the fraction ``1/(1 + a)``.  The bypassed gas rejoins after the turbine-outlet
    thermocouple (which reads the turbine's own outlet); ``T_exh`` is the mixed temperature after the
    junction.  opening : :class:`Schedule` of ``a`` (0 closed).
    """

    opening: Schedule

    def __post_init__(self) -> None:
        if not isinstance(self.opening, Schedule):
            raise ValueError(f"waste_gate.opening must be a Schedule, got {type(self.opening).__name__}")
        if self.opening.max > 5.0:
            raise ValueError(f"waste_gate.opening (A_wg/A_eff) must lie in [0, 5], got {list(self.opening.value)}")


@dataclass(frozen=True)
class BypassValve:
    """Charge air from the charge-air receiver (x4, after the cooler at T_c) to the turbine inlet (Σ3, Σ4).

    Orifice flow ``ṁ_bp = α_z A_eff b sqrt(2 ρ_c (x4 - x3))`` with ``ρ_c = x4/(R_a T_c)``, zero when the
    receiver pressure x3 is not below x4 (a non-return valve).  The compressor delivers the cylinders'
    air plus ṁ_bp, the turbine receives the exhaust plus ṁ_bp at the mixed temperature.
    opening : :class:`Schedule` of ``b = A_bp/A_eff`` (0 closed).
    junction : where the bypass air meets the exhaust: ``receiver`` (in the exhaust receiver, upstream of
    the turbine-inlet thermocouple, which reads the mixture) or ``turbine`` (between that thermocouple and
    the turbine: the thermocouple reads the exhaust alone, the turbine the mixture).
    """

    opening: Schedule
    junction: str = "receiver"

    def __post_init__(self) -> None:
        if not isinstance(self.opening, Schedule):
            raise ValueError(f"bypass_valve.opening must be a Schedule, got {type(self.opening).__name__}")
        if self.opening.max > 2.0:
            raise ValueError(f"bypass_valve.opening (A_bp/A_eff) must lie in [0, 2], got {list(self.opening.value)}")
        if self.junction not in BYPASS_JUNCTIONS:
            raise ValueError(
                f"bypass_valve.junction must be one of {', '.join(BYPASS_JUNCTIONS)}, got {self.junction!r}"
            )


@dataclass(frozen=True)
class TurbineFlowLaw:
    """Turbine swallowing capacity (eq. 3.16 generalised).

    ``ṁ sqrt(R_g T) = α_z A_eff s x3 sqrt(1 - (p_ex/x3)^e)``: ``area_scale`` s scales the effective area,
    ``exponent`` e = 2 is Stodola's ellipse law of the base model (a larger e makes the turbine pass more at
    low pressure ratio: a flow capacity less sensitive to the pressure ratio, nozzle-like).
    """

    area_scale: float = 1.0
    exponent: float = 2.0

    def __post_init__(self) -> None:
        _in_range("turbine_flow_law", "area_scale", self.area_scale, 0.3, 3.0)
        _in_range("turbine_flow_law", "exponent", self.exponent, 1.0, 6.0)


@dataclass(frozen=True)
class TurbineEfficiencyBSR:
    """Turbine efficiency as a function of the blade-speed ratio ν = u/c_s (eq. 3.26 extended).

    The rotor tip speed u follows the compressor (constant isentropic head coefficient, as the
    turbocharger-speed law of :mod:`.turbocharger_speed`), ``u ∝ sqrt(Δh_c,is(x4))``; the spouting
    velocity ``c_s = sqrt(2 c_p,g T_t (1 - Π))``.  With ``r = ν/ν_nom`` (1 at the base model's nominal
    point) the turbine and overall efficiencies are multiplied by
    ``(1 - w (r/r_opt - 1)^2) / (1 - w (1/r_opt - 1)^2)`` (1 at the nominal point).
    bsr_opt_rel : r_opt, the blade-speed ratio of best efficiency relative to the nominal one.
    curvature : w.
    """

    bsr_opt_rel: float = 1.0
    curvature: float = 0.5

    def __post_init__(self) -> None:
        _in_range("turbine_efficiency_bsr", "bsr_opt_rel", self.bsr_opt_rel, 0.3, 3.0)
        _in_range("turbine_efficiency_bsr", "curvature", self.curvature, 0.0, 0.99)


@dataclass(frozen=True)
class ExhaustHeatLoss:
    """Heat lost by the exhaust in the manifold between the cylinders and the turbine (Σ3).

    ``T_after = T_w + (T_cyl - T_w) exp(-NTU)`` with the wall at the ambient temperature and
    ``NTU = NTU_nom (ṁ_g / ṁ_g,nom)^(-e)``: a convective coefficient growing as ṁ^(1-e) (turbulent pipe
    flow: e = 0.2), so the relative loss grows as the flow falls.  loss_fraction_nom :
    ``1 - exp(-NTU_nom)`` at the nominal exhaust flow.  flow_exponent : e.
    """

    loss_fraction_nom: float = 0.05
    flow_exponent: float = 0.2

    def __post_init__(self) -> None:
        _in_range("exhaust_heat_loss", "loss_fraction_nom", self.loss_fraction_nom, 0.0, 0.6)
        _in_range("exhaust_heat_loss", "flow_exponent", self.flow_exponent, 0.0, 2.0)


SUBMODEL_TYPES: dict[str, type] = {
    "speed_law": CombinatorSpeed,
    "friction": ExtraFriction,
    "turbocharger_map": TurbochargerMap,
    "intercooler": Intercooler,
    "cylinder_heat_loss": CylinderHeatLoss,
    "waste_gate": WasteGate,
    "bypass_valve": BypassValve,
    "turbine_flow_law": TurbineFlowLaw,
    "turbine_efficiency_bsr": TurbineEfficiencyBSR,
    "exhaust_heat_loss": ExhaustHeatLoss,
}


@dataclass(frozen=True)
class EngineSubmodels:
    """The optional submodels of one engine (``None`` = off, the base model of the thesis)."""

    speed_law: CombinatorSpeed | None = None
    friction: ExtraFriction | None = None
    turbocharger_map: TurbochargerMap | None = None
    intercooler: Intercooler | None = None
    cylinder_heat_loss: CylinderHeatLoss | None = None
    waste_gate: WasteGate | None = None
    bypass_valve: BypassValve | None = None
    turbine_flow_law: TurbineFlowLaw | None = None
    turbine_efficiency_bsr: TurbineEfficiencyBSR | None = None
    exhaust_heat_loss: ExhaustHeatLoss | None = None

    def __post_init__(self) -> None:
        for name, typ in SUBMODEL_TYPES.items():
            v = getattr(self, name)
            if v is not None and not isinstance(v, typ):
                raise ValueError(f"submodel {name!r} must be a {typ.__name__} or None, got {type(v).__name__}")

    def replace(self, **changes: Any) -> "EngineSubmodels":
        unknown = set(changes) - set(SUBMODEL_TYPES)
        if unknown:
            raise ValueError(f"unknown submodel(s) {', '.join(sorted(unknown))}; known: {', '.join(SUBMODEL_TYPES)}")
        return dataclasses.replace(self, **changes)

    def active(self) -> list[str]:
        """Names of the submodels that are on."""
        return [k for k in SUBMODEL_TYPES if getattr(self, k) is not None]

    @property
    def any(self) -> bool:
        return bool(self.active())

    # ---- serialisation (the fitted-engine JSON file)
    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for k in self.active():
            v = getattr(self, k)
            d = {}
            for f in dataclasses.fields(v):
                x = getattr(v, f.name)
                d[f.name] = x.as_dict() if isinstance(x, Schedule) else x
            out[k] = d
        return out

    @classmethod
    def from_dict(cls, d: Mapping[str, Any] | None) -> "EngineSubmodels":
        """Build from ``{submodel: {field: value}}`` (schedules as ``{"u": [...], "value": [...]}``);
        errors name the submodel and field."""
        if not d:
            return NO_SUBMODELS
        if not isinstance(d, Mapping):
            raise ValueError(f"submodels must be an object {{name: {{field: value}}}}, got {type(d).__name__}")
        kw: dict[str, Any] = {}
        for name, fields in d.items():
            typ = SUBMODEL_TYPES.get(name)
            if typ is None:
                raise ValueError(f"unknown submodel {name!r}; known: {', '.join(SUBMODEL_TYPES)}")
            if fields is None:
                continue
            if not isinstance(fields, Mapping):
                raise ValueError(f"submodel {name!r} must be an object of its fields, got {fields!r}")
            allowed = {f.name: f for f in dataclasses.fields(typ)}
            bad = set(fields) - set(allowed)
            if bad:
                raise ValueError(
                    f"submodel {name!r}: unknown field(s) {', '.join(sorted(bad))}; known: {', '.join(allowed)}"
                )
            vals = {}
            for k, v in fields.items():
                vals[k] = Schedule.from_dict(v, f"{name}.{k}") if k == "opening" else v
            try:
                kw[name] = typ(**vals)
            except TypeError as e:
                raise ValueError(f"submodel {name!r}: {e}") from None
        return cls(**kw)


NO_SUBMODELS = EngineSubmodels()
