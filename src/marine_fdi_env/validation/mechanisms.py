"""The library of named physical mechanisms that can explain where the base model misses the data.

Each mechanism is a small dataclass: a few parameters (name, unit, default, plausible range, the
range synthetic data draw from, the tolerance within which a fit should recover it), a docstring
with the physical explanation, the quantities it touches and :meth:`Mechanism.apply`, which switches
on the hooks of :class:`~.extended_model.ExtendedModel` it needs.  Mechanisms touch disjoint hooks,
so any combination composes by applying them in turn.

=========================  ====================================================================
id                         hook of the extended model
=========================  ====================================================================
cpp_load                   speed law: combinator line instead of the propeller law (eq. 3.11)
friction_losses            extra friction mean effective pressure (Chen-Flynn-like) in eq. 3.10
ambient_conditions         ambient temperature and pressure (and turbine back pressure)
turbocharger_map           efficiency map instead of the polynomial of eq. 3.33
bypass_valve               charge air bypassing the cylinders to the exhaust receiver
intercooler_effectiveness  cooler outlet temperature following the cooler inlet (load)
cylinder_heat_loss         polytropic exponents of compression and expansion
sensor_calibration         gain and offset of one measured channel
=========================  ====================================================================

Ranges.  ``bounds`` is the plausible range (the fit stays inside it); ``draw`` is the part of it
that the synthetic-data generator draws from for the hidden-effect tests.  ``draw`` leaves out
values so close to the base model that their effect is below 1 % measurement noise (an effect the
data cannot show cannot be identified from them); it is the *detectable* part of the plausible
range, stated here so that the identification rate is a statement about detectable effects.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar, Mapping, Sequence

import numpy as np

from .extended_model import Hooks

__all__ = [
    "Param", "Mechanism", "CppLoad", "FrictionLosses", "AmbientConditions", "TurbochargerMap", "BypassValve",
    "IntercoolerEffectiveness", "CylinderHeatLoss", "SensorCalibration", "MECHANISM_IDS", "PHYSICAL_MECHANISMS",
    "get_mechanism", "library", "sensor_reference", "hooks_for", "parse_mechanism_spec",
]


@dataclass(frozen=True)
class Param:
    """A mechanism parameter.

    bounds : plausible range (fits stay inside).  draw : intervals synthetic data draw from (uniform in
    an interval chosen with probability proportional to its width).  tolerance : how close a fit on
    data with 1 % noise should recover it (the hidden-effect tests use it).  starts : extra starting
    values for the fit (multi-start where the cost has several minima, e.g. a threshold).
    """

    name: str
    unit: str
    default: float
    bounds: tuple[float, float]
    draw: tuple[tuple[float, float], ...]
    tolerance: float
    description: str
    starts: tuple[float, ...] = ()

    def sample(self, rng: np.random.Generator, full_range: bool = False) -> float:
        """A random value from ``draw`` (``full_range``: uniform over the whole plausible range ``bounds``)."""
        if full_range:
            return float(rng.uniform(*self.bounds))
        widths = np.array([hi - lo for lo, hi in self.draw], float)
        k = int(rng.choice(len(self.draw), p=widths / widths.sum())) if len(self.draw) > 1 else 0
        lo, hi = self.draw[k]
        return float(rng.uniform(lo, hi))

    def as_dict(self) -> dict:
        return {"name": self.name, "unit": self.unit, "default": self.default, "bounds": list(self.bounds),
                "draw": [list(d) for d in self.draw], "tolerance": self.tolerance, "description": self.description}


@dataclass(frozen=True)
class Mechanism:
    """Base class: a named mechanism with parameters and the hooks it sets."""

    id: ClassVar[str] = ""
    title: ClassVar[str] = ""
    touches: ClassVar[tuple[str, ...]] = ()

    @property
    def label(self) -> str:
        """Unique name of this instance (``sensor_calibration[column]`` for the per-channel one)."""
        return self.id

    @property
    def params(self) -> tuple[Param, ...]:
        """The mechanism's parameters (every subclass defines them)."""
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
            raise ValueError(f"mechanism {self.label}: unknown parameter(s) {', '.join(sorted(unknown))}; "
                             f"known: {', '.join(self.param_names)}")
        out = self.defaults()
        out.update({k: float(v) for k, v in given.items()})
        return out

    def apply(self, hooks: Hooks, values: Mapping[str, float], params) -> Hooks:
        """Hooks with this mechanism switched on at parameter ``values`` (``params``: the engine's);
        every subclass defines it."""
        raise TypeError(f"{type(self).__name__} does not define how it modifies the model")

    def describe(self) -> dict:
        return {"id": self.id, "label": self.label, "title": self.title, "touches": list(self.touches),
                "explanation": " ".join((type(self).__doc__ or "").split()),
                "parameters": [p.as_dict() for p in self.params]}


ALL_OUTPUTS = ("charge_air_pressure_Pa", "exhaust_receiver_pressure_Pa", "p_max_Pa", "compressor_outlet_temperature_K",
               "turbine_inlet_temperature_K", "turbine_outlet_temperature_K", "air_mass_flow_kg_s",
               "exhaust_mass_flow_kg_s", "fuel_mass_flow_kg_s", "sfc_kg_per_J")


@dataclass(frozen=True)
class CppLoad(Mechanism):
    """Controllable-pitch propeller: speed and power are set independently.

    The base model ties speed to power by the fixed-pitch propeller law ``P = c n^3`` (eq. 3.11).  A
    CPP installation runs a combinator schedule instead: the speed is held high while the pitch sets
    the load, typically rising linearly from ``s0 n_nom`` at zero load to ``s1 n_nom`` at full load.
    At part load the engine then turns faster with less torque than on the propeller curve: more
    friction, a smaller constant-volume heat release (X_cv falls with speed, eq. 3.12), less slip
    time per cycle and a different turbocharger match.  The speed channel shows it directly, every
    other channel through the speed.  Hook: ``speed_law = "combinator"``.
    """

    id: ClassVar[str] = "cpp_load"
    title: ClassVar[str] = "controllable-pitch propeller (combinator speed line)"
    touches: ClassVar[tuple[str, ...]] = ("engine_speed_rev_s",) + ALL_OUTPUTS

    @property
    def params(self) -> tuple[Param, ...]:
        return (
            Param("speed_zero_load_rel", "-", 0.8, (0.3, 1.1), ((0.72, 0.95),), 0.03,
                  "engine speed at zero load / nominal speed", starts=(0.6, 1.0)),
            Param("speed_full_load_rel", "-", 1.0, (0.85, 1.1), ((0.97, 1.02),), 0.02,
                  "engine speed at full load / nominal speed"),
        )

    def apply(self, hooks, values, params):
        return hooks.replace(speed_law="combinator", speed_zero_load_rel=values["speed_zero_load_rel"],
                             speed_full_load_rel=values["speed_full_load_rel"])


@dataclass(frozen=True)
class FrictionLosses(Mechanism):
    """Mechanical losses that weigh more at part load (Chen-Flynn friction mean effective pressure).

    Chen and Flynn write the friction mean effective pressure as ``fmep = A + B p_max + C c_m +
    D c_m^2`` (c_m: mean piston speed).  The base model has a friction torque linear in speed
    (eq. 3.10) calibrated at the nominal point only.  This mechanism adds ``Δfmep = a + d (n/n_nom)^2``:
    a constant part ``a`` (auxiliaries, ring pack, bearings at low speed), whose share of the brake
    work grows as the load falls, and a part ``d`` growing with the square of the piston speed
    (hydrodynamic and windage losses).  More friction needs more fuel for the same brake power: fuel
    flow and SFC rise (most at part load for ``a``), and the extra fuel heats the exhaust and drives
    the turbocharger harder.  Hooks: ``fmep_a_Pa``, ``fmep_d_Pa``.
    """

    id: ClassVar[str] = "friction_losses"
    title: ClassVar[str] = "friction mean effective pressure (Chen-Flynn-like)"
    touches: ClassVar[tuple[str, ...]] = ("fuel_mass_flow_kg_s", "sfc_kg_per_J") + ALL_OUTPUTS[:8]

    @property
    def params(self) -> tuple[Param, ...]:
        return (
            Param("fmep_offset_bar", "bar", 0.0, (-1.5, 3.0), ((0.4, 1.5),), 0.15,
                  "constant part of the extra friction mean effective pressure"),
            Param("fmep_speed2_bar", "bar", 0.0, (-2.0, 3.0), ((0.0, 1.0),), 0.3,
                  "extra friction mean effective pressure at nominal speed growing with (n/n_nom)^2"),
        )

    def apply(self, hooks, values, params):
        return hooks.replace(fmep_a_Pa=values["fmep_offset_bar"] * 1e5, fmep_d_Pa=values["fmep_speed2_bar"] * 1e5)


@dataclass(frozen=True)
class AmbientConditions(Mechanism):
    """Air temperature and pressure at the compressor inlet differ from the model's.

    The parameter set fixes the ambient state (ISO 25 °C / 1 bar for the MAN set, assumed for the
    Birka shop tests, which did not record it).  A warmer intake needs more compressor work per
    pressure ratio (r_TC = T_in/T_amb falls in eq. 3.31) and raises the compressor outlet
    temperature one to one; a lower ambient pressure lowers the absolute charge and receiver
    pressures in proportion and the turbine back pressure with them.  Hooks: ``dT_amb_K``,
    ``dp_amb_Pa`` (through ``params.replace``: T_amb_K, p_amb_Pa and p_ex_Pa).
    """

    id: ClassVar[str] = "ambient_conditions"
    title: ClassVar[str] = "ambient air temperature and pressure"
    touches: ClassVar[tuple[str, ...]] = ALL_OUTPUTS[:8]

    @property
    def params(self) -> tuple[Param, ...]:
        return (
            Param("dT_amb_K", "K", 0.0, (-35.0, 35.0), ((-20.0, -8.0), (8.0, 20.0)), 3.0,
                  "ambient temperature minus the parameter set's"),
            Param("dp_amb_kPa", "kPa", 0.0, (-10.0, 6.0), ((-5.0, -2.0), (1.5, 3.0)), 0.6,
                  "ambient pressure minus the parameter set's"),
        )

    def apply(self, hooks, values, params):
        return hooks.replace(dT_amb_K=values["dT_amb_K"], dp_amb_Pa=values["dp_amb_kPa"] * 1e3)


@dataclass(frozen=True)
class TurbochargerMap(Mechanism):
    """Turbocharger efficiency from a map instead of the polynomial of eq. 3.33.

    Eq. 3.33 makes the overall turbocharger efficiency a parabola in the charge pressure that falls
    from 0.69 at nominal to 0.43 at 1 bar: a turbocharger that gives up at part load (docs/model.md
    §5).  A real turbocharger's efficiency follows its compressor and turbine maps and stays much
    flatter along the engine's operating line.  The mechanism replaces eq. 3.33 by
    ``η_TC = s η_TC(p1_nom) (1 - w (x4/p1_nom - 1)^2)``: ``s`` scales the efficiency at the nominal
    charge pressure, ``w`` sets how fast it falls away from it (eq. 3.33 corresponds to w ≈ 0.6).
    The turbine efficiency keeps the calibration's ratio ``η_turbo = η_TC/(η_c η_com)``, so the
    compressor stays isentropic at η_c.  A flatter map raises the charge pressure, air flow and
    compressor outlet temperature at part load and cools the exhaust.  Hooks: ``tc_map``,
    ``tc_eta_scale``, ``tc_curvature``.
    """

    id: ClassVar[str] = "turbocharger_map"
    title: ClassVar[str] = "turbocharger efficiency map"
    touches: ClassVar[tuple[str, ...]] = ALL_OUTPUTS[:8]

    @property
    def params(self) -> tuple[Param, ...]:
        return (
            Param("eta_scale", "-", 1.0, (0.75, 1.25), ((0.93, 0.97), (1.03, 1.07)), 0.015,
                  "turbocharger efficiency at the nominal charge pressure / eq. 3.33's"),
            Param("curvature", "-", 0.3, (0.0, 1.5), ((0.0, 0.35),), 0.06,
                  "relative efficiency drop per (x4/p1_nom - 1)^2"),
        )

    def apply(self, hooks, values, params):
        return hooks.replace(tc_map=True, tc_eta_scale=values["eta_scale"], tc_curvature=values["curvature"])


@dataclass(frozen=True)
class BypassValve(Mechanism):
    """Cylinder bypass: charge air flows straight to the exhaust receiver above a charge pressure.

    Many medium-speed engines have a bypass from the charge-air receiver to the exhaust receiver
    that opens near full load (the thesis suspects one behind its misfit near nominal speed).  The
    bypassed air leaves the compressor, skips the cylinders and mixes with the exhaust before the
    turbine at the cooler outlet temperature: the compressor delivers more air than the cylinders
    take, the turbine gets more but cooler gas.  The fraction of the compressor flow bypassed rises
    smoothly from 0 at ``threshold x p1_nom`` to ``max_fraction`` at ``(threshold + 0.15) p1_nom``.
    It lowers the turbine inlet and outlet temperatures and raises the air and exhaust flows at high
    load, leaving part load untouched.  Hooks: ``bypass_max_fraction``, ``bypass_threshold_rel``.
    """

    id: ClassVar[str] = "bypass_valve"
    title: ClassVar[str] = "cylinder bypass / waste gate above a charge pressure"
    touches: ClassVar[tuple[str, ...]] = ALL_OUTPUTS[:8]
    width_rel: ClassVar[float] = 0.15

    @property
    def params(self) -> tuple[Param, ...]:
        return (
            Param("max_fraction", "-", 0.05, (0.0, 0.3), ((0.06, 0.15),), 0.02,
                  "fraction of the compressor air flow bypassed when fully open"),
            Param("threshold_rel", "-", 0.7, (0.3, 1.1), ((0.55, 0.8),), 0.05,
                  "charge pressure / p1_nom at which the valve starts to open", starts=(0.45, 0.9)),
        )

    def apply(self, hooks, values, params):
        return hooks.replace(bypass_max_fraction=values["max_fraction"], bypass_threshold_rel=values["threshold_rel"],
                             bypass_width_rel=self.width_rel)


@dataclass(frozen=True)
class IntercoolerEffectiveness(Mechanism):
    """Charge-air cooler outlet temperature that follows the load.

    Eq. 3.37 takes the cooler outlet temperature T_c as a constant.  A cooler of effectiveness ε
    cools the air to ``T_c = T_cw + (1 - ε)(T_in,cooler - T_cw)``: its outlet follows its inlet, the
    compressor outlet temperature, which rises with the charge pressure.  Anchored at the model's
    T_c at the nominal charge pressure, ``T_c = T_c,nom + (1 - ε)(T_co(x4) - T_co(p1_nom))`` with the
    isentropic compressor outlet ``T_co`` at η_c.  A less effective cooler (smaller ε) gives cooler
    air at part load and warmer air above nominal, changing the trapped mass (eq. 3.29), the air
    excess ratio and the exhaust temperatures.  Hook: ``intercooler_effectiveness``.
    """

    id: ClassVar[str] = "intercooler_effectiveness"
    title: ClassVar[str] = "intercooler effectiveness (load-dependent cooler outlet)"
    touches: ClassVar[tuple[str, ...]] = ("charge_air_cooler_outlet_temperature_K", "inlet_air_temperature_K") \
        + ALL_OUTPUTS[:8]

    @property
    def params(self) -> tuple[Param, ...]:
        return (
            Param("effectiveness", "-", 0.9, (0.3, 1.0), ((0.7, 0.9),), 0.03,
                  "cooler effectiveness (1: constant outlet temperature)"),
        )

    def apply(self, hooks, values, params):
        return hooks.replace(intercooler_effectiveness=values["effectiveness"])


@dataclass(frozen=True)
class CylinderHeatLoss(Mechanism):
    """Heat transfer to the cylinder walls changes the polytropic exponents.

    The Seiliger cycle compresses isentropically (exponent κa = 1.4, eq. B.1-B.9) and expands with
    the fixed polytropic exponent n_exp.  Heat lost to the walls during compression lowers the
    compression exponent (``n_comp < κa``): lower compression temperature and peak pressure.  More
    (or less) heat loss during expansion raises (lowers) the expansion exponent: less (more)
    expansion work, a cooler (hotter) exhaust.  Both change the indicated work and so the fuel
    needed for the brake power.  Hooks: ``n_comp`` (the derived r_c^n, r_c^(n-1)) and ``n_exp``
    (a parameter, through ``params.replace``).
    """

    id: ClassVar[str] = "cylinder_heat_loss"
    title: ClassVar[str] = "cylinder heat loss (polytropic exponents)"
    touches: ClassVar[tuple[str, ...]] = ("p_max_Pa",) + ALL_OUTPUTS

    @property
    def params(self) -> tuple[Param, ...]:
        return (
            Param("n_comp", "-", 1.4, (1.25, 1.42), ((1.31, 1.37),), 0.01,
                  "compression polytropic exponent (isentropic: kappa_a = 1.4)"),
            Param("dn_exp", "-", 0.0, (-0.15, 0.12), ((-0.08, -0.03), (0.03, 0.08)), 0.012,
                  "expansion polytropic exponent minus the parameter set's n_exp"),
        )

    def apply(self, hooks, values, params):
        return hooks.replace(n_comp=values["n_comp"], n_exp=params.n_exp + values["dn_exp"])


@dataclass(frozen=True)
class SensorCalibration(Mechanism):
    """Gain and offset error of one measured channel: ``reading = gain * true + offset``.

    A transmitter out of calibration (span and zero), a thermocouple at the wrong place, a gauge
    reading taken as absolute: the model is right and one sensor is not.  It touches only its own
    channel; a physical mechanism moves several channels together, which is how the two are told
    apart.  ``reference`` scales the offset's range: the channel's mean absolute value in its units, at
    least 100 for temperatures (a thermocouple's zero error does not shrink with a low reading in °C;
    see :func:`sensor_reference`).
    Hook: ``sensors[column] = (gain, offset)`` (column units).
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
            Param("gain", "-", 1.0, (0.8, 1.2), ((0.92, 0.96), (1.04, 1.08)), 0.03, "span error of the reading"),
            Param("offset", "column unit", 0.0, (-0.15 * r, 0.15 * r), ((-0.04 * r, -0.01 * r), (0.01 * r, 0.04 * r)),
                  0.03 * r, "zero error of the reading, in the column's unit"),
        )

    def sample(self, rng: np.random.Generator, full_range: bool = False) -> dict[str, float]:
        """Gain and offset drawn with the same sign of error, so that they do not cancel at the typical
        reading (a gain of 0.95 with an offset of +5 % of the reading would be no error there)."""
        v = super().sample(rng, full_range)
        if not full_range and (v["gain"] - 1.0) * v["offset"] < 0:
            v["offset"] = -v["offset"]
        return v

    def apply(self, hooks, values, params):
        return hooks.with_sensor(self.channel, values["gain"], values["offset"])

    def describe(self) -> dict:
        d = super().describe()
        d["channel"] = self.channel
        d["reference"] = self.reference
        return d


PHYSICAL_MECHANISMS: tuple[Mechanism, ...] = (
    CppLoad(), FrictionLosses(), AmbientConditions(), TurbochargerMap(), BypassValve(), IntercoolerEffectiveness(),
    CylinderHeatLoss(),
)
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


def sensor_reference(column: str, values) -> float:
    """Scale of a channel's sensor offset: mean absolute value in the column's units (>= 100 for
    temperatures)."""
    from .columns import COLUMNS, QUANTITIES

    v = np.asarray(values, float)
    ref = float(np.nanmean(np.abs(v))) if np.any(np.isfinite(v)) else 1.0
    spec = COLUMNS.get(column)
    q = QUANTITIES.get(spec.quantity) if spec is not None else None
    if q is not None and q.kind == "temperature":
        ref = max(ref, 100.0)
    return ref if ref > 0 else 1.0


def library(channels: Sequence[str] = (), references: Mapping[str, float] | None = None) -> list[Mechanism]:
    """The physical mechanisms plus one sensor calibration per channel."""
    refs = references or {}
    return list(PHYSICAL_MECHANISMS) + [SensorCalibration(channel=c, reference=float(refs.get(c, 1.0)))
                                        for c in channels]


def hooks_for(mechanisms: Sequence[tuple[Mechanism, Mapping[str, float]]], params, base: Hooks | None = None) -> Hooks:
    """Compose the hooks of several (mechanism, values) pairs."""
    h = base if base is not None else Hooks()
    for m, v in mechanisms:
        h = m.apply(h, m.values(v), params)
    return h


def parse_mechanism_spec(spec: str) -> tuple[str, dict[str, float], str | None]:
    """Parse ``ID[:param=value,...]`` (``sensor_calibration`` also takes ``channel=COLUMN``).

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
                raise ValueError(f"mechanism {mech_id}: value of {key!r} must be a number, got {val.strip()!r}") \
                    from None
            if not math.isfinite(values[key]):
                raise ValueError(f"mechanism {mech_id}: value of {key!r} must be finite")
    if mech_id != "none":
        m = get_mechanism(mech_id, channel or "placeholder")
        unknown = set(values) - set(m.param_names)
        if unknown:
            raise ValueError(f"mechanism {mech_id}: unknown parameter(s) {', '.join(sorted(unknown))}; known: "
                             f"{', '.join(m.param_names)}" + (", channel" if mech_id == SensorCalibration.id else ""))
    return mech_id, values, channel
