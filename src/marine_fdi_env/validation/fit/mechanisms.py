"""The library of named physical mechanisms that can explain where the base model misses the data.

Each mechanism is a small dataclass: a few parameters (name, unit, default, plausible range, the
range synthetic data draw from, the tolerance within which a fit should recover it), a docstring
with the physical explanation, the quantities it touches and :meth:`Mechanism.apply`, which switches on
the engine submodel it stands for (:mod:`marine_fdi_env.engine.submodels`) in a :class:`~.problem.Setting`.
A selected mechanism is therefore part of the one engine model: the fitted engine runs in the
simulator, the steady-state solver, the environment and the diagnoser.

=============================  ==========================================================================
id                             submodel / effect
=============================  ==========================================================================
cpp_load                       ``speed_law``: combinator line instead of the propeller law (eq. 3.11)
friction_losses                ``friction``: extra friction mean effective pressure (eq. 3.10)
ambient_conditions             offsets of the ambient temperature and pressure (and turbine back pressure)
turbocharger_map               ``turbocharger_map``: efficiency map instead of the polynomial of eq. 3.33
intercooler_effectiveness      ``intercooler``: cooler outlet following the cooler inlet, and its level
cylinder_heat_loss             ``cylinder_heat_loss``: polytropic exponents of compression and expansion
turbine_flow_law               ``turbine_flow_law``: swallowing capacity (area scale, ellipse-law exponent)
turbine_efficiency_bsr         ``turbine_efficiency_bsr``: efficiency vs blade-speed ratio
exhaust_heat_loss              ``exhaust_heat_loss``: manifold heat loss growing as the flow falls
waste_gate                     ``waste_gate``: exhaust bypassing the turbine, opening per measured point
bypass_valve                   ``bypass_valve``: charge air to the turbine inlet, opening per measured point
sensor_calibration             gain and offset of one measured channel (a measurement, not the engine)
=============================  ==========================================================================

Valve-type mechanisms (:class:`ValveMechanism`) have one opening per measured point instead of global
parameters: a valve acts at some operating points and not at others (a waste gate that opens near
full load, a bypass opened at part load), and the points where it acts are part of the answer.  The
fit (:mod:`.fitting`) selects them without enumerating subsets: a relaxation with a sparsity penalty,
then a confirmation refit.  The openings become a :class:`~marine_fdi_env.engine.submodels.Schedule` over the
fuel setting for the fitted engine.

Ranges.  ``bounds`` is the plausible range (the fit stays inside it); ``draw`` is the part of it that
the synthetic-data generator draws from for the hidden-effect study: the part whose effect exceeds
both the measurement noise and the model-error nuisance (:mod:`.nuisance`), stated here so that the
identification rate is a statement about effects the data can show.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar, Mapping, Sequence

import numpy as np

from ...engine.submodels import (
    BypassValve,
    CombinatorSpeed,
    CylinderHeatLoss,
    ExhaustHeatLoss,
    ExtraFriction,
    Intercooler,
    Schedule,
    TurbineEfficiencyBSR,
    TurbineFlowLaw,
    TurbochargerMap,
    WasteGate,
)

__all__ = [
    "Param",
    "Mechanism",
    "ValveMechanism",
    "CppLoad",
    "FrictionLosses",
    "AmbientConditions",
    "TurbochargerMapM",
    "IntercoolerEffectiveness",
    "CylinderHeatLossM",
    "TurbineFlowLawM",
    "TurbineEfficiencyBSRM",
    "ExhaustHeatLossM",
    "WasteGateM",
    "BypassValveM",
    "SensorCalibration",
    "MECHANISM_IDS",
    "PHYSICAL_MECHANISMS",
    "VALVE_MECHANISMS",
    "get_mechanism",
    "library",
    "sensor_reference",
    "parse_mechanism_spec",
    "STRUCTURAL_EQUIVALENTS",
    "equivalents",
]


@dataclass(frozen=True)
class Param:
    """A mechanism parameter.

    bounds : plausible range (fits stay inside).  draw : intervals synthetic data draw from (uniform in
    an interval chosen with probability proportional to its width).  tolerance : how close a fit on
    data with 1 % noise should recover it (the hidden-effect study uses it).  starts : extra starting
    values for the fit (multi-start where the cost has several minima).  natural : whether the lower and
    upper bounds are natural limits (a flat map, no heat loss, an ideal cooler) rather than the end of what is
    plausible; a fit pinned at a bound that is not natural is not named (:mod:`.select.selection`).
    """

    name: str
    unit: str
    default: float
    bounds: tuple[float, float]
    draw: tuple[tuple[float, float], ...]
    tolerance: float
    description: str
    starts: tuple[float, ...] = ()
    natural: tuple[bool, bool] = (False, False)

    def pinned(self, value: float, rel: float = 1e-3) -> str | None:
        """``"lower"``/``"upper"`` when ``value`` sits at a bound of the plausible range that is not a natural limit
        (a fit pinned there wants more than the mechanism can physically give), else ``None``."""
        lo, hi = self.bounds
        span = hi - lo
        if not self.natural[0] and value <= lo + rel * span:
            return "lower"
        if not self.natural[1] and value >= hi - rel * span:
            return "upper"
        return None

    def sample(self, rng: np.random.Generator, full_range: bool = False) -> float:
        """A random value from ``draw`` (``full_range``: uniform over the whole plausible range ``bounds``)."""
        if full_range:
            return float(rng.uniform(*self.bounds))
        widths = np.array([hi - lo for lo, hi in self.draw], float)
        k = int(rng.choice(len(self.draw), p=widths / widths.sum())) if len(self.draw) > 1 else 0
        lo, hi = self.draw[k]
        return float(rng.uniform(lo, hi))

    def as_dict(self) -> dict:
        return {
            "name": self.name,
            "unit": self.unit,
            "default": self.default,
            "bounds": list(self.bounds),
            "draw": [list(d) for d in self.draw],
            "tolerance": self.tolerance,
            "description": self.description,
        }


@dataclass(frozen=True)
class Mechanism:
    """Base class: a named mechanism with parameters and the model change it makes."""

    id: ClassVar[str] = ""
    title: ClassVar[str] = ""
    touches: ClassVar[tuple[str, ...]] = ()
    pointwise: ClassVar[bool] = False

    @property
    def label(self) -> str:
        """Unique name of this instance (``sensor_calibration[column]`` for the per-channel one)."""
        return self.id

    @property
    def params(self) -> tuple[Param, ...]:
        """The mechanism's global parameters (every subclass defines them)."""
        raise TypeError(f"{type(self).__name__} does not define its parameters")

    @property
    def param_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.params)

    def defaults(self) -> dict[str, float]:
        return {p.name: p.default for p in self.params}

    def sample(self, rng: np.random.Generator, full_range: bool = False) -> dict[str, float]:
        return {p.name: p.sample(rng, full_range) for p in self.params}

    def values(self, given: Mapping[str, float] | None = None) -> dict[str, float]:
        """Defaults overridden by ``given``; unknown names raise ``ValueError``."""
        given = dict(given or {})
        unknown = set(given) - set(self.param_names)
        if unknown:
            raise ValueError(
                f"mechanism {self.label}: unknown parameter(s) {', '.join(sorted(unknown))}; "
                f"known: {', '.join(self.param_names)}"
            )
        out = self.defaults()
        out.update({k: float(v) for k, v in given.items()})
        return out

    def apply(self, setting, values: Mapping[str, float], params):
        """``setting`` with this mechanism switched on at parameter ``values`` (``params``: the engine's)."""
        raise TypeError(f"{type(self).__name__} does not define how it modifies the model")

    def describe(self) -> dict:
        return {
            "id": self.id,
            "label": self.label,
            "title": self.title,
            "touches": list(self.touches),
            "pointwise": self.pointwise,
            "explanation": " ".join((type(self).__doc__ or "").split()),
            "parameters": [p.as_dict() for p in self.params],
        }


ALL_OUTPUTS = (
    "charge_air_pressure_Pa",
    "exhaust_receiver_pressure_Pa",
    "p_max_Pa",
    "compressor_outlet_temperature_K",
    "turbine_inlet_temperature_K",
    "turbine_outlet_temperature_K",
    "air_mass_flow_kg_s",
    "exhaust_mass_flow_kg_s",
    "fuel_mass_flow_kg_s",
    "sfc_kg_per_J",
    "turbocharger_speed_rev_s",
    "cylinder_outlet_temperature_K",
)
GAS_PATH = (
    "charge_air_pressure_Pa",
    "exhaust_receiver_pressure_Pa",
    "compressor_outlet_temperature_K",
    "turbine_inlet_temperature_K",
    "turbine_outlet_temperature_K",
    "air_mass_flow_kg_s",
    "exhaust_mass_flow_kg_s",
    "turbocharger_speed_rev_s",
    "p_max_Pa",
    "cylinder_outlet_temperature_K",
)


@dataclass(frozen=True)
class CppLoad(Mechanism):
    """Controllable-pitch propeller: speed and power are set independently.

    The base model ties speed to power by the fixed-pitch propeller law ``P = c n^3`` (eq. 3.11).  A
    CPP installation runs a combinator schedule instead: the speed is held high while the pitch sets
    the load, typically rising linearly from ``s0 n_nom`` at zero load to ``s1 n_nom`` at full load.
    At part load the engine then turns faster with less torque than on the propeller curve: more
    friction, a smaller constant-volume heat release (X_cv falls with speed, eq. 3.12), less slip
    time per cycle and a different turbocharger match.  Submodel ``speed_law``.
    """

    id: ClassVar[str] = "cpp_load"
    title: ClassVar[str] = "controllable-pitch propeller (combinator speed line)"
    touches: ClassVar[tuple[str, ...]] = ("engine_speed_rev_s",) + ALL_OUTPUTS

    @property
    def params(self) -> tuple[Param, ...]:
        return (
            Param(
                "speed_zero_load_rel",
                "-",
                0.8,
                (0.3, 1.1),
                ((0.72, 0.95),),
                0.03,
                "engine speed at zero load / nominal speed",
                starts=(0.6, 1.0),
            ),
            Param(
                "speed_full_load_rel",
                "-",
                1.0,
                (0.85, 1.1),
                ((0.97, 1.02),),
                0.02,
                "engine speed at full load / nominal speed",
            ),
        )

    def apply(self, setting, values, params):
        return setting.with_submodel(
            speed_law=CombinatorSpeed(values["speed_zero_load_rel"], values["speed_full_load_rel"])
        )


@dataclass(frozen=True)
class FrictionLosses(Mechanism):
    """Mechanical losses that weigh more at part load (Chen-Flynn friction mean effective pressure).

    Chen and Flynn write the friction mean effective pressure as ``fmep = A + B p_max + C c_m +
    D c_m^2`` (c_m: mean piston speed).  The base model has a friction torque linear in speed
    (eq. 3.10) calibrated at the nominal point only.  This mechanism adds ``Δfmep = a + d (n/n_nom)^2``:
    a constant part ``a`` (auxiliaries, ring pack, bearings at low speed), whose share of the brake
    work grows as the load falls, and a part ``d`` growing with the square of the piston speed.  More
    friction needs more fuel for the same brake power: fuel flow and SFC rise (most at part load for
    ``a``), and the extra fuel heats the exhaust and drives the turbocharger harder.  Submodel ``friction``.
    """

    id: ClassVar[str] = "friction_losses"
    title: ClassVar[str] = "friction mean effective pressure (Chen-Flynn-like)"
    touches: ClassVar[tuple[str, ...]] = ALL_OUTPUTS

    @property
    def params(self) -> tuple[Param, ...]:
        return (
            Param(
                "fmep_offset_bar",
                "bar",
                0.0,
                (-1.5, 3.0),
                ((0.6, 1.5),),
                0.15,
                "constant part of the extra friction mean effective pressure",
            ),
            Param(
                "fmep_speed2_bar",
                "bar",
                0.0,
                (-2.0, 3.0),
                ((0.0, 1.0),),
                0.3,
                "extra friction mean effective pressure at nominal speed growing with (n/n_nom)^2",
            ),
        )

    def apply(self, setting, values, params):
        return setting.with_submodel(
            friction=ExtraFriction(values["fmep_offset_bar"] * 1e5, values["fmep_speed2_bar"] * 1e5)
        )


@dataclass(frozen=True)
class AmbientConditions(Mechanism):
    """Air temperature and pressure at the compressor inlet differ from what the model assumes.

    Without ambient records the model runs at the parameter set's ambient state (ISO 25 C / 1 bar for
    the sibling sets); with per-row records it runs at the recorded state, and this mechanism is a bias
    of those records.  A warmer intake needs more compressor work per pressure ratio and raises the
    compressor outlet temperature one to one; a lower ambient pressure lowers the absolute charge and
    receiver pressures in proportion and the turbine back pressure with them.
    """

    id: ClassVar[str] = "ambient_conditions"
    title: ClassVar[str] = "ambient air temperature and pressure"
    touches: ClassVar[tuple[str, ...]] = GAS_PATH

    @property
    def params(self) -> tuple[Param, ...]:
        return (
            Param(
                "dT_amb_K",
                "K",
                0.0,
                (-35.0, 35.0),
                ((-20.0, -10.0), (10.0, 20.0)),
                3.0,
                "ambient temperature minus the assumed/recorded one",
            ),
            Param(
                "dp_amb_kPa",
                "kPa",
                0.0,
                (-10.0, 6.0),
                ((-5.0, -2.5), (2.5, 4.0)),
                0.6,
                "ambient pressure minus the assumed/recorded one",
            ),
        )

    def apply(self, setting, values, params):
        return setting.replace(dT_amb_K=values["dT_amb_K"], dp_amb_Pa=values["dp_amb_kPa"] * 1e3)


@dataclass(frozen=True)
class TurbochargerMapM(Mechanism):
    """Turbocharger efficiency from a map instead of the polynomial of eq. 3.33.

    Eq. 3.33 makes the overall turbocharger efficiency a parabola in the charge pressure that falls
    from 0.69 at nominal to 0.43 at 1 bar: a turbocharger that gives up at part load (docs/model.md
    §5).  A real turbocharger's efficiency follows its compressor and turbine maps and stays much
    flatter along the engine's operating line.  ``η_TC = s η_TC(p1_nom) (1 - w (x4/p1_nom - 1)^2)``:
    ``s`` scales the efficiency at the nominal charge pressure, ``w`` sets how fast it falls away from it
    (eq. 3.33 corresponds to w ≈ 0.6).  A flatter map raises the charge pressure, air flow and
    compressor outlet temperature at part load and cools the exhaust.  Submodel ``turbocharger_map``.
    """

    id: ClassVar[str] = "turbocharger_map"
    title: ClassVar[str] = "turbocharger efficiency map"
    touches: ClassVar[tuple[str, ...]] = GAS_PATH

    @property
    def params(self) -> tuple[Param, ...]:
        return (
            Param(
                "eta_scale",
                "-",
                1.0,
                (0.75, 1.25),
                ((0.86, 0.92), (1.08, 1.14)),
                0.02,
                "turbocharger efficiency at the nominal charge pressure / eq. 3.33's",
            ),
            Param(
                "curvature",
                "-",
                0.3,
                (0.0, 1.5),
                ((0.0, 0.3),),
                0.08,
                "relative efficiency drop per (x4/p1_nom - 1)^2",
                natural=(True, False),
            ),
        )

    def apply(self, setting, values, params):
        return setting.with_submodel(turbocharger_map=TurbochargerMap(values["eta_scale"], values["curvature"]))


@dataclass(frozen=True)
class IntercoolerEffectiveness(Mechanism):
    """Charge-air cooler outlet temperature that follows the load, at a level set by the cooling water.

    Eq. 3.37 takes the cooler outlet temperature T_c as a constant.  A cooler of effectiveness ε cools
    the air to ``T_c = T_cw + (1 - ε)(T_in,cooler - T_cw)``: its outlet follows its inlet, the compressor
    outlet temperature, which rises with the charge pressure; the level follows the cooling water.
    ``T_c = T_c,nom + dT + (1 - ε)(T_co,is(x4) - T_co,is(p1_nom))``.  A colder or less effective cooler
    changes the trapped mass (eq. 3.29), the air excess ratio and the exhaust temperatures.
    Submodel ``intercooler``.
    """

    id: ClassVar[str] = "intercooler_effectiveness"
    title: ClassVar[str] = "intercooler effectiveness and outlet level"
    touches: ClassVar[tuple[str, ...]] = (
        "charge_air_cooler_outlet_temperature_K",
        "inlet_air_temperature_K",
    ) + ALL_OUTPUTS

    @property
    def params(self) -> tuple[Param, ...]:
        return (
            Param(
                "effectiveness",
                "-",
                0.9,
                (0.3, 1.0),
                ((0.6, 0.85),),
                0.04,
                "cooler effectiveness (1: outlet independent of the load)",
                natural=(False, True),
            ),
            Param(
                "dT_outlet_K",
                "K",
                0.0,
                (-40.0, 40.0),
                ((-20.0, -8.0), (8.0, 20.0)),
                2.0,
                "cooler outlet at the nominal charge pressure minus the parameter set's T_c",
            ),
        )

    def apply(self, setting, values, params):
        return setting.with_submodel(intercooler=Intercooler(values["effectiveness"], values["dT_outlet_K"]))


@dataclass(frozen=True)
class CylinderHeatLossM(Mechanism):
    """Heat transfer to the cylinder walls changes the polytropic exponents.

    The Seiliger cycle compresses isentropically (exponent κa = 1.4, eq. B.1-B.9) and expands with the
    fixed polytropic exponent n_exp.  Heat lost to the walls during compression lowers the compression
    exponent (``n_comp < κa``): lower compression temperature and peak pressure.  More (or less) heat
    loss during expansion raises (lowers) the expansion exponent: less (more) expansion work, a cooler
    (hotter) exhaust.  Both change the indicated work and so the fuel needed for the brake power.
    Submodel ``cylinder_heat_loss``.
    """

    id: ClassVar[str] = "cylinder_heat_loss"
    title: ClassVar[str] = "cylinder heat loss (polytropic exponents)"
    touches: ClassVar[tuple[str, ...]] = ALL_OUTPUTS

    @property
    def params(self) -> tuple[Param, ...]:
        return (
            Param(
                "n_comp",
                "-",
                1.4,
                (1.25, 1.42),
                ((1.30, 1.35),),
                0.01,
                "compression polytropic exponent (isentropic: kappa_a = 1.4)",
                natural=(False, True),
            ),
            Param(
                "dn_exp",
                "-",
                0.0,
                (-0.15, 0.12),
                ((-0.08, -0.04), (0.04, 0.08)),
                0.012,
                "expansion polytropic exponent minus the parameter set's n_exp",
            ),
        )

    def apply(self, setting, values, params):
        return setting.with_submodel(cylinder_heat_loss=CylinderHeatLoss(values["n_comp"], values["dn_exp"]))


@dataclass(frozen=True)
class TurbineFlowLawM(Mechanism):
    """Turbine swallowing capacity differs from the base model's (eq. 3.16).

    The base model passes the exhaust through the effective area A_eff derived at the nominal point with
    Stodola's ellipse law ``ṁ sqrt(R T)/(α A x3) = sqrt(1 - (p_ex/x3)^2)``.  A turbine with a smaller
    nozzle ring (or partly blocked) swallows less: the receiver pressure rises, so does the turbine's
    expansion ratio and work.  The exponent shapes how the flow capacity varies with the pressure ratio:
    a larger one makes the turbine pass relatively more at low pressure ratio (part load).  Its plausible
    range starts just below Stodola's 2: a single-stage turbocharger turbine lies between the ellipse law
    of a multistage turbine and a nozzle (whose flow capacity saturates above the critical pressure ratio,
    a larger exponent); one that swallows *less* at low pressure ratio than the ellipse law is not a turbine
    we know of (a radial turbine swallows more at low rotor speed, not less).  The receiver (turbine inlet)
    pressure shows it directly.  Submodel ``turbine_flow_law``.
    """

    id: ClassVar[str] = "turbine_flow_law"
    title: ClassVar[str] = "turbine swallowing capacity (effective area, ellipse-law exponent)"
    touches: ClassVar[tuple[str, ...]] = GAS_PATH

    @property
    def params(self) -> tuple[Param, ...]:
        return (
            Param(
                "area_scale",
                "-",
                1.0,
                (0.5, 1.6),
                ((0.72, 0.86), (1.14, 1.3)),
                0.02,
                "turbine effective area / the parameter set's A_eff",
            ),
            Param(
                "exponent",
                "-",
                2.0,
                (1.8, 6.0),
                ((2.8, 4.5),),
                0.3,
                "pressure-ratio exponent of the ellipse law (2: Stodola; larger: towards a nozzle)",
            ),
        )

    def apply(self, setting, values, params):
        return setting.with_submodel(turbine_flow_law=TurbineFlowLaw(values["area_scale"], values["exponent"]))


@dataclass(frozen=True)
class TurbineEfficiencyBSRM(Mechanism):
    """Turbine efficiency falls away from its best blade-speed ratio.

    A turbine converts the gas's isentropic enthalpy drop best at one ratio of rotor tip speed to
    spouting velocity ``ν = u/c_s`` (about 0.7 for a radial turbine).  Along the engine's operating line
    the tip speed follows the compressor's head and the spouting velocity the turbine's drop; where the
    ratio moves away from the optimum the efficiency falls as ``1 - w (ν/ν_opt - 1)²``.  With an optimum
    away from the nominal ratio, the part-load (or overload) efficiency differs from eq. 3.26's.
    Submodel ``turbine_efficiency_bsr``.

    Not separable from ``turbocharger_map`` on steady-state data (:data:`STRUCTURAL_EQUIVALENTS`): with the
    compressor's constant head coefficient (the turbocharger-speed law) the turbocharger power balance ties
    ``ν² ∝ δ η_TC``, so along the operating line the blade-speed ratio is a function of the charge pressure and
    the factor is one more efficiency map over x4.  Telling them apart needs a compressor map (a head
    coefficient varying with the flow) or transients.
    """

    id: ClassVar[str] = "turbine_efficiency_bsr"
    title: ClassVar[str] = "turbine efficiency vs blade-speed ratio"
    touches: ClassVar[tuple[str, ...]] = GAS_PATH

    @property
    def params(self) -> tuple[Param, ...]:
        return (
            Param(
                "bsr_opt_rel",
                "-",
                1.0,
                (0.5, 2.0),
                ((0.6, 0.8), (1.25, 1.6)),
                0.06,
                "blade-speed ratio of best efficiency / the nominal one",
                starts=(0.7, 1.4),
            ),
            Param(
                "curvature", "-", 0.5, (0.0, 0.95), ((0.5, 0.9),), 0.15, "relative efficiency drop per (ν/ν_opt - 1)^2"
            ),
        )

    def apply(self, setting, values, params):
        return setting.with_submodel(
            turbine_efficiency_bsr=TurbineEfficiencyBSR(values["bsr_opt_rel"], values["curvature"])
        )


@dataclass(frozen=True)
class ExhaustHeatLossM(Mechanism):
    """The exhaust loses heat in the manifold before the turbine, most at low flow.

    Between the exhaust valves and the turbine the gas gives heat to the manifold walls (water-cooled or
    lagged).  The convective coefficient grows as ṁ^0.8 (turbulent pipe flow), so the relative loss,
    ``1 - exp(-NTU)`` with ``NTU ∝ ṁ^(-e)``, grows as the flow falls: the turbine inlet runs cooler than the
    cylinder outlets, most at part load, and the turbine gets less enthalpy.  Submodel ``exhaust_heat_loss``.
    """

    id: ClassVar[str] = "exhaust_heat_loss"
    title: ClassVar[str] = "exhaust manifold heat loss (growing as the flow falls)"
    touches: ClassVar[tuple[str, ...]] = GAS_PATH

    @property
    def params(self) -> tuple[Param, ...]:
        return (
            Param(
                "loss_fraction_nom",
                "-",
                0.05,
                (0.0, 0.4),
                ((0.06, 0.15),),
                0.02,
                "relative temperature loss towards ambient at the nominal exhaust flow",
                natural=(True, False),
            ),
            Param(
                "flow_exponent",
                "-",
                0.2,
                (0.0, 1.5),
                ((0.3, 0.8),),
                0.15,
                "NTU ~ (flow / nominal flow)^(-exponent)",
                natural=(True, False),
            ),
        )

    def apply(self, setting, values, params):
        return setting.with_submodel(
            exhaust_heat_loss=ExhaustHeatLoss(values["loss_fraction_nom"], values["flow_exponent"])
        )


@dataclass(frozen=True)
class ValveMechanism(Mechanism):
    """A valve with one opening per measured point (no global parameters).

    opening_max : the plausible range is [0, opening_max].  opening_scale : a typical opening (the unit of
    the sparsity penalty).  draw_max : openings synthetic data draw from when the valve acts.
    """

    pointwise: ClassVar[bool] = True
    opening_max: ClassVar[float] = 1.0
    opening_scale: ClassVar[float] = 0.1
    draw_range: ClassVar[tuple[float, float]] = (0.1, 0.3)
    opening_unit: ClassVar[str] = "-"

    @property
    def params(self) -> tuple[Param, ...]:
        return ()

    def with_openings(self, setting, openings: np.ndarray):
        """``setting`` with the valve on and ``openings`` at the measured points (NaN: the schedule)."""
        raise TypeError(f"{type(self).__name__} does not define its valve")

    def with_schedule(self, setting, schedule: Schedule):
        raise TypeError(f"{type(self).__name__} does not define its valve")

    def activity_key(self) -> str:
        """The summary key of the flow fraction the valve diverts."""
        raise TypeError(f"{type(self).__name__} does not define its valve")

    def apply(self, setting, values, params):
        return setting


@dataclass(frozen=True)
class WasteGateM(ValveMechanism):
    """A waste gate lets exhaust bypass the turbine.

    Near full load many engines open a waste gate to hold the charge-air pressure (and the
    turbocharger speed) below a limit: part of the exhaust flows from the receiver around the turbine
    through an orifice and rejoins after it.  The receiver pressure and the turbine's power fall with
    the opening; the charge-air pressure, compressor outlet temperature and turbocharger speed stop
    rising with load, and more fuel per kW heats the cylinders' exhaust.  The opening ``a = A_wg/A_eff``
    is found per measured point (0 where the gate is shut).

    A waste-gated turbocharger has a smaller turbine than one without: it is matched to give the charge
    pressure at part load, and the gate spills what the smaller turbine would over-deliver near full load.
    The parameter set's turbine area is derived at the nominal point with no gate, so the mechanism re-matches
    it: ``turbine_area_scale`` multiplies A_eff (one global parameter).  Submodel ``waste_gate`` (and the
    turbine area of the fitted engine).
    """

    id: ClassVar[str] = "waste_gate"
    title: ClassVar[str] = "waste gate (exhaust bypassing a re-matched turbine)"
    touches: ClassVar[tuple[str, ...]] = GAS_PATH
    opening_max: ClassVar[float] = 1.0
    opening_scale: ClassVar[float] = 0.1
    draw_range: ClassVar[tuple[float, float]] = (0.12, 0.35)
    opening_unit: ClassVar[str] = "A_wg/A_eff"

    @property
    def params(self) -> tuple[Param, ...]:
        return (
            Param(
                "turbine_area_scale",
                "-",
                0.9,
                (0.5, 1.2),
                ((0.7, 0.9),),
                0.03,
                "turbine effective area of the waste-gated turbocharger / the parameter set's A_eff",
                starts=(0.75,),
            ),
        )

    def apply(self, setting, values, params):
        return setting.replace(area_scale=values["turbine_area_scale"])

    def with_openings(self, setting, openings):
        sub = setting.submodels
        ws = sub.waste_gate if sub.waste_gate is not None else _WG_SHUT
        return setting.replace(
            submodels=sub.replace(waste_gate=ws), valves={**setting.valves, "waste_gate": np.asarray(openings, float)}
        )

    def with_schedule(self, setting, schedule):
        v = {k: x for k, x in setting.valves.items() if k != "waste_gate"}
        return setting.replace(submodels=setting.submodels.replace(waste_gate=WasteGate(schedule)), valves=v)

    def activity_key(self) -> str:
        return "waste_gate_fraction"


@dataclass(frozen=True)
class BypassValveM(ValveMechanism):
    """A bypass valve sends charge air straight to the turbine inlet.

    Engines run on the propeller curve often open a bypass from the charge-air receiver to the exhaust
    before the turbine at part load: the compressor then delivers more air than the cylinders take,
    moving it away from surge, and the turbine gets more (cooler) gas, which raises the turbocharger
    speed and the charge-air pressure.  Orifice flow ``ṁ_bp = α A_eff b sqrt(2 ρ (x4 - x3))`` while the
    charge air is above the receiver pressure; the opening ``b = A_bp/A_eff`` is found per measured point
    (0 where the valve is shut).  The bypass air joins in the exhaust receiver, upstream of the
    turbine-inlet thermocouple (``junction = "receiver"``).  Submodel ``bypass_valve``.
    """

    id: ClassVar[str] = "bypass_valve"
    title: ClassVar[str] = "bypass valve (charge air to the turbine inlet)"
    touches: ClassVar[tuple[str, ...]] = GAS_PATH
    opening_max: ClassVar[float] = 0.6
    opening_scale: ClassVar[float] = 0.05
    draw_range: ClassVar[tuple[float, float]] = (0.06, 0.2)
    opening_unit: ClassVar[str] = "A_bp/A_eff"
    junction: ClassVar[str] = "receiver"

    def with_openings(self, setting, openings):
        sub = setting.submodels
        bv = _BP_SHUT[self.junction]
        return setting.replace(
            submodels=sub.replace(bypass_valve=bv),
            valves={**setting.valves, "bypass_valve": np.asarray(openings, float)},
        )

    def with_schedule(self, setting, schedule):
        v = {k: x for k, x in setting.valves.items() if k != "bypass_valve"}
        return setting.replace(
            submodels=setting.submodels.replace(bypass_valve=BypassValve(schedule, self.junction)), valves=v
        )

    def activity_key(self) -> str:
        return "bypass_fraction"


@dataclass(frozen=True)
class SensorCalibration(Mechanism):
    """Gain and offset error of one measured channel: ``reading = gain * true + offset``.

    A transmitter out of calibration (span and zero), a thermocouple at the wrong place, a gauge
    reading taken as absolute: the model is right and one sensor is not.  It touches only its own
    channel; a physical mechanism moves several channels together, which is how the two are told
    apart.  ``reference`` scales the offset's range: the channel's mean absolute value in its units, at
    least 100 for temperatures (see :func:`sensor_reference`).
    """

    channel: str = ""
    reference: float = 1.0

    id: ClassVar[str] = "sensor_calibration"
    title: ClassVar[str] = "sensor gain/offset on one channel"

    @property
    def label(self) -> str:
        return f"{self.id}[{self.channel}]"

    @property
    def touches(self) -> tuple[str, ...]:  # type: ignore[override]
        return (self.channel,)

    @property
    def params(self) -> tuple[Param, ...]:
        r = abs(self.reference) if self.reference and math.isfinite(self.reference) else 1.0
        return (
            Param("gain", "-", 1.0, (0.6, 1.4), ((0.92, 0.96), (1.04, 1.08)), 0.03, "span error of the reading"),
            Param(
                "offset",
                "column unit",
                0.0,
                (-0.3 * r, 0.3 * r),
                ((-0.06 * r, -0.02 * r), (0.02 * r, 0.06 * r)),
                0.03 * r,
                "zero error of the reading, in the column's unit",
            ),
        )

    def sample(self, rng: np.random.Generator, full_range: bool = False) -> dict[str, float]:
        """Gain and offset drawn with the same sign of error, so that they do not cancel at the typical
        reading (a gain of 0.95 with an offset of +5 % of the reading would be no error there)."""
        v = super().sample(rng, full_range)
        if not full_range and (v["gain"] - 1.0) * v["offset"] < 0:
            v["offset"] = -v["offset"]
        return v

    def apply(self, setting, values, params):
        return setting.replace(sensors={**setting.sensors, self.channel: (values["gain"], values["offset"])})

    def describe(self) -> dict:
        d = super().describe()
        d["channel"] = self.channel
        d["reference"] = self.reference
        return d


# Mechanisms that steady-state data cannot tell apart (the model gives them the same family of effects); the
# report names the others of a class beside a selected one, and the open-world study counts a named member of
# the true one's class as identified only in its "up to equivalence" rate.
STRUCTURAL_EQUIVALENTS: tuple[frozenset[str], ...] = (frozenset({"turbocharger_map", "turbine_efficiency_bsr"}),)


def equivalents(mech_id: str) -> frozenset[str]:
    """The other mechanisms of ``mech_id``'s structural-equivalence class (empty if none)."""
    for cls in STRUCTURAL_EQUIVALENTS:
        if mech_id in cls:
            return cls - {mech_id}
    return frozenset()


_WG_SHUT = WasteGate(Schedule.constant(0.0))
_BP_SHUT = {j: BypassValve(Schedule.constant(0.0), j) for j in ("receiver", "turbine")}

PHYSICAL_MECHANISMS: tuple[Mechanism, ...] = (
    CppLoad(),
    FrictionLosses(),
    AmbientConditions(),
    TurbochargerMapM(),
    IntercoolerEffectiveness(),
    CylinderHeatLossM(),
    TurbineFlowLawM(),
    TurbineEfficiencyBSRM(),
    ExhaustHeatLossM(),
    WasteGateM(),
    BypassValveM(),
)
VALVE_MECHANISMS = tuple(m for m in PHYSICAL_MECHANISMS if m.pointwise)
MECHANISM_IDS = tuple(m.id for m in PHYSICAL_MECHANISMS) + (SensorCalibration.id,)


def get_mechanism(mech_id: str, channel: str | None = None, reference: float = 1.0) -> Mechanism:
    """The mechanism of ``mech_id`` (``sensor_calibration`` needs ``channel``)."""
    for m in PHYSICAL_MECHANISMS:
        if m.id == mech_id:
            return m
    if mech_id == SensorCalibration.id:
        if not channel:
            raise ValueError("sensor_calibration needs a channel (a measured column)")
        return SensorCalibration(channel=channel, reference=reference)
    raise ValueError(f"unknown mechanism {mech_id!r}; known: {', '.join(MECHANISM_IDS)}")


def sensor_reference(column: str, values, kind: str | None = None) -> float:
    """Scale of a channel's sensor offset: mean absolute value in the column's units (>= 100 for
    temperatures)."""
    from ..measured.columns import QUANTITIES, lookup_column

    v = np.asarray(values, float)
    ref = float(np.nanmean(np.abs(v))) if np.any(np.isfinite(v)) else 1.0
    if kind is None:
        spec = lookup_column(column)
        q = QUANTITIES.get(spec.quantity) if spec is not None else None
        kind = q.kind if q is not None else None
    if kind == "temperature":
        ref = max(ref, 100.0)
    return ref if ref > 0 else 1.0


def library(channels: Sequence[str] = (), references: Mapping[str, float] | None = None) -> list[Mechanism]:
    """The physical mechanisms plus one sensor calibration per channel."""
    refs = references or {}
    return list(PHYSICAL_MECHANISMS) + [
        SensorCalibration(channel=c, reference=float(refs.get(c, 1.0))) for c in channels
    ]


def parse_mechanism_spec(spec: str) -> tuple[str, dict[str, float], str | None]:
    """Parse ``ID[:param=value,...]`` (``sensor_calibration`` also takes ``channel=COLUMN``; a valve takes
    ``opening=A`` for a constant opening, or ``above=L`` / ``below=L`` to open it above/below load fraction L
    with ``opening=A``).

    Returns (id, given parameter values, channel or ``None``); raises ``ValueError`` naming the problem.
    """
    text = spec.strip()
    if not text:
        raise ValueError("empty mechanism spec")
    mech_id, _, rest = text.partition(":")
    mech_id = mech_id.strip()
    if mech_id != "none" and mech_id not in MECHANISM_IDS:
        raise ValueError(f"unknown mechanism {mech_id!r}; known: none, {', '.join(MECHANISM_IDS)}")
    values: dict[str, float] = {}
    channel = None
    if rest.strip():
        if mech_id == "none":
            raise ValueError("mechanism 'none' takes no parameters")
        for item in rest.split(","):
            key, eq, val = item.partition("=")
            key = key.strip()
            if not eq or not key:
                raise ValueError(f"mechanism {mech_id}: expected param=value, got {item.strip()!r}")
            if key == "channel" and mech_id == SensorCalibration.id:
                channel = val.strip()
                continue
            try:
                values[key] = float(val)
            except ValueError:
                raise ValueError(
                    f"mechanism {mech_id}: value of {key!r} must be a number, got {val.strip()!r}"
                ) from None
            if not math.isfinite(values[key]):
                raise ValueError(f"mechanism {mech_id}: value of {key!r} must be finite")
    if mech_id != "none":
        m = get_mechanism(mech_id, channel or "placeholder")
        known = set(m.param_names) | ({"opening", "above", "below"} if m.pointwise else set())
        unknown = set(values) - known
        if unknown:
            raise ValueError(
                f"mechanism {mech_id}: unknown parameter(s) {', '.join(sorted(unknown))}; known: "
                f"{', '.join(sorted(known))}" + (", channel" if mech_id == SensorCalibration.id else "")
            )
    return mech_id, values, channel
